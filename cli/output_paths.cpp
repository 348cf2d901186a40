#include "cli/output_paths.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

namespace mbscope::cli {

namespace fs = std::filesystem;

std::optional<std::string> cannot_write_file(const std::string& path) {
    std::error_code ec;
    if (fs::is_directory(path, ec)) return path + ": is a directory";
    if (fs::exists(path, ec)) {
        if (::access(path.c_str(), W_OK) != 0) return path + ": " + std::strerror(errno);
        // access() answers yes to root for any file; opening it for writing (without truncating or writing)
        // asks the file system. Devices and FIFOs are left to the write: opening them may block or act.
        if (fs::is_regular_file(path, ec)) {
            const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
            if (fd < 0) return path + ": " + std::strerror(errno);
            ::close(fd);
        }
        return std::nullopt;
    }
    const fs::path parent =
        fs::path(path).parent_path().empty() ? fs::path(".") : fs::path(path).parent_path();
    if (!fs::is_directory(parent, ec)) return path + ": no directory " + parent.string();
    if (::access(parent.c_str(), W_OK | X_OK) != 0) return path + ": " + std::strerror(errno);
    return std::nullopt;
}

std::optional<std::string> cannot_use_directory(const std::string& dir) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) return dir + ": " + ec.message();
    if (!fs::is_directory(dir, ec)) return dir + ": not a directory";
    if (::access(dir.c_str(), W_OK | X_OK) != 0) return dir + ": " + std::strerror(errno);
    return std::nullopt;
}

}  // namespace mbscope::cli
