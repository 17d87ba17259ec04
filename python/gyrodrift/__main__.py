import sys

try:
    from gyrodrift.cli import main
except KeyboardInterrupt:  # Ctrl-C before main() handles it: the same one line and code
    print("gyrodrift: interrupted", file=sys.stderr)
    sys.exit(130)

sys.exit(main())
