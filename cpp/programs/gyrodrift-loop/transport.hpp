// Byte/frame transports of the loop: a serial device (tty or pty, raw mode via termios) and
// a SocketCAN raw socket. Everything is opened non-blocking; the fixed-rate loop polls.
#pragma once
#include <fcntl.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#if defined(__linux__) && __has_include(<linux/can.h>) && __has_include(<linux/can/raw.h>)
#include <linux/can.h>
#include <linux/can/raw.h>
#define GYRODRIFT_HAVE_SOCKETCAN 1
#else
#define GYRODRIFT_HAVE_SOCKETCAN 0
#endif

namespace gyrodrift::loop {

inline speed_t baud_constant(long baud) noexcept {
  switch (baud) {
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 500000: return B500000;
    case 576000: return B576000;
    case 921600: return B921600;
    case 1000000: return B1000000;
    case 1500000: return B1500000;
    case 2000000: return B2000000;
    case 3000000: return B3000000;
    case 4000000: return B4000000;
    default: return B0;
  }
}

// Opens "fd:N" (an inherited descriptor, e.g. a pty master from the harness) or a device
// path, non-blocking, and puts a tty into raw 8N1 at the given baud (a pty accepts and
// ignores the baud). Returns the fd or -1 with `error` set.
inline int open_serial(const std::string& spec, long baud, std::string& error) {
  int fd = -1;
  if (spec.rfind("fd:", 0) == 0) {
    char* end = nullptr;
    const long n = std::strtol(spec.c_str() + 3, &end, 10);
    if (end == spec.c_str() + 3 || *end != '\0' || n < 0 || n > 65535) {
      error = "bad descriptor spec '" + spec + "' (expected fd:N)";
      return -1;
    }
    fd = static_cast<int>(n);
    if (fcntl(fd, F_GETFD) < 0) {
      error = "descriptor " + spec + " is not open: " + std::strerror(errno);
      return -1;
    }
  } else {
    fd = open(spec.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
      error = "cannot open serial device '" + spec + "': " + std::strerror(errno);
      return -1;
    }
  }
  const int fl = fcntl(fd, F_GETFL);
  if (fl < 0 || fcntl(fd, F_SETFL, fl | O_NONBLOCK) < 0) {
    error = "cannot make '" + spec + "' non-blocking: " + std::strerror(errno);
    return -1;
  }
  if (isatty(fd) != 0) {
    termios tio{};
    if (tcgetattr(fd, &tio) != 0) {
      error = "tcgetattr('" + spec + "'): " + std::strerror(errno);
      return -1;
    }
    cfmakeraw(&tio);
    tio.c_cflag |= static_cast<tcflag_t>(CLOCAL | CREAD);
    tio.c_cflag &= static_cast<tcflag_t>(~(CSTOPB | PARENB | CRTSCTS));
    tio.c_cc[VMIN] = 0;
    tio.c_cc[VTIME] = 0;
    const speed_t sp = baud_constant(baud);
    if (sp == B0) {
      error = "unsupported baud rate " + std::to_string(baud);
      return -1;
    }
    cfsetispeed(&tio, sp);
    cfsetospeed(&tio, sp);
    if (tcsetattr(fd, TCSANOW, &tio) != 0) {
      error = "tcsetattr('" + spec + "'): " + std::strerror(errno);
      return -1;
    }
  }
  return fd;
}

// Opens a raw SocketCAN socket bound to `ifname` (e.g. can0, vcan0).
inline int open_socketcan(const std::string& ifname, std::string& error) {
#if GYRODRIFT_HAVE_SOCKETCAN
  const int fd = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    error = "SocketCAN is not available in this kernel (socket(PF_CAN): " +
            std::string(std::strerror(errno)) + "); use --slcan DEVICE with a USB-CAN adapter";
    return -1;
  }
  if (ifname.size() >= IFNAMSIZ) {
    error = "CAN interface name too long: " + ifname;
    close(fd);
    return -1;
  }
  ifreq ifr{};
  std::memcpy(ifr.ifr_name, ifname.c_str(), ifname.size());
  if (ioctl(fd, SIOCGIFINDEX, &ifr) < 0) {
    error = "no CAN interface '" + ifname + "': " + std::strerror(errno);
    close(fd);
    return -1;
  }
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifr.ifr_ifindex;
  if (bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0) {
    error = "bind to CAN interface '" + ifname + "': " + std::strerror(errno);
    close(fd);
    return -1;
  }
  return fd;
#else
  (void)ifname;
  error = "this build has no SocketCAN support (no <linux/can.h>); use --slcan DEVICE";
  return -1;
#endif
}

}  // namespace gyrodrift::loop
