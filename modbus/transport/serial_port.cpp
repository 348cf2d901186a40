#include "modbus/transport/serial_port.hpp"

#include <fcntl.h>
#include <pty.h>
#include <termios.h>

#include <cerrno>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <string_view>

namespace mbscope::modbus::transport {

namespace {

speed_t speed_of(std::uint32_t baud) noexcept {
    switch (baud) {
        case 300:
            return B300;
        case 600:
            return B600;
        case 1200:
            return B1200;
        case 2400:
            return B2400;
        case 4800:
            return B4800;
        case 9600:
            return B9600;
        case 19200:
            return B19200;
        case 38400:
            return B38400;
        case 57600:
            return B57600;
        case 115200:
            return B115200;
        case 230400:
            return B230400;
        default:
            return 0;
    }
}

std::string make_raw(int fd, const SerialLine& line, bool pty) {
    termios tio{};
    if (tcgetattr(fd, &tio) != 0) return std::string("tcgetattr: ") + std::strerror(errno);
    cfmakeraw(&tio);
    tio.c_cflag |= CLOCAL | CREAD;
    tio.c_cflag &= ~(CSIZE | PARENB | PARODD | CSTOPB | CRTSCTS);
    tio.c_cflag |= line.data_bits == 7 ? CS7 : CS8;
    if (line.parity != Parity::None) tio.c_cflag |= PARENB;
    if (line.parity == Parity::Odd) tio.c_cflag |= PARODD;
    if (line.stop_bits == 2) tio.c_cflag |= CSTOPB;
    tio.c_cc[VMIN] = 0;
    tio.c_cc[VTIME] = 0;
    const speed_t speed = speed_of(line.baud);
    if (speed == 0) return "unsupported baud rate " + std::to_string(line.baud);
    cfsetispeed(&tio, speed);
    cfsetospeed(&tio, speed);
    if (tcsetattr(fd, TCSANOW, &tio) != 0) {
        // A pseudo-terminal carries bytes, not characters: it has no parity or stop bit to set, and recent
        // kernels refuse PARENB and 7-bit characters on one (EINVAL). The line's settings still give t1.5 and
        // t3.5. A real port that refuses them is an error.
        if (!pty || errno != EINVAL) return std::string("tcsetattr: ") + std::strerror(errno);
        tio.c_cflag = (tio.c_cflag & ~(PARENB | PARODD | CSTOPB | CSIZE)) | CS8;
        if (tcsetattr(fd, TCSANOW, &tio) != 0) return std::string("tcsetattr: ") + std::strerror(errno);
    }
    return {};
}

}  // namespace

Result<void, std::string> set_line(int fd, const SerialLine& line, bool pty) {
    if (auto err = make_raw(fd, line, pty); !err.empty()) return err;
    return {};
}

bool is_pty(const std::string& device) {
    char resolved[PATH_MAX];
    return ::realpath(device.c_str(), resolved) != nullptr &&
           std::string_view(resolved).starts_with("/dev/pts/");
}

Result<UniqueFd, std::string> open_serial(const std::string& device, const SerialLine& line) {
    UniqueFd fd(::open(device.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC));
    if (!fd) return device + ": " + std::strerror(errno);
    if (auto err = make_raw(fd.get(), line, is_pty(device)); !err.empty()) return device + ": " + err;
    return fd;
}

Result<Pty, std::string> open_pty(const SerialLine& line) {
    int master = -1, slave = -1;
    char name[256] = {};
    if (openpty(&master, &slave, name, nullptr, nullptr) != 0)
        return std::string("openpty: ") + std::strerror(errno);
    Pty pty{UniqueFd(master), UniqueFd(slave), name};
    // Raw on both sides: the client side is what a Modbus master opens and must not translate CR/LF.
    if (auto err = make_raw(slave, line, true); !err.empty()) return "pty: " + err;
    if (auto err = make_raw(master, line, true); !err.empty()) return "pty: " + err;
    const int flags = fcntl(master, F_GETFL);
    if (flags < 0 || fcntl(master, F_SETFL, flags | O_NONBLOCK) != 0)
        return std::string("pty: ") + std::strerror(errno);
    fcntl(master, F_SETFD, FD_CLOEXEC);
    fcntl(slave, F_SETFD, FD_CLOEXEC);
    return pty;
}

}  // namespace mbscope::modbus::transport
