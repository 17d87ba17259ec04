import sys

from gyrodrift.cli import main

sys.exit(main())
