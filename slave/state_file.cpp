#include "slave/state_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

namespace mbscope::slave {

using nlohmann::json;

namespace {

std::string errno_text(const std::string& what) {
    return what + ": " + std::strerror(errno);
}

modbus::Result<void, std::string> write_all(int fd, const std::string& data, const std::string& path) {
    std::size_t done = 0;
    while (done < data.size()) {
        const ssize_t n = ::write(fd, data.data() + done, data.size() - done);
        if (n < 0) {
            if (errno == EINTR) continue;
            return errno_text(path + ": write");
        }
        done += static_cast<std::size_t>(n);
    }
    return {};
}

}  // namespace

modbus::Result<void, std::string> save_state(const std::string& path, const std::vector<Device*>& devices) {
    json doc{{"format", "mbscope-slave-state/1"}, {"units", json::object()}};
    for (const Device* d : devices) {
        json unit{{"profile", d->profile().id}};
        for (const auto& [table, values] : d->image().changes()) {
            json t = json::object();
            for (const auto& [address, value] : values)
                t[std::to_string(address)] = value;
            unit[std::string(modbus::to_string(table))] = std::move(t);
        }
        doc["units"][std::to_string(d->unit())] = std::move(unit);
    }
    const std::string data = doc.dump(1) + "\n";
    const std::string tmp = path + ".tmp";
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) return errno_text(tmp + ": open");
    auto written = write_all(fd, data, tmp);
    if (written && ::fsync(fd) != 0) written = errno_text(tmp + ": fsync");
    ::close(fd);
    if (!written) return written;
    if (::rename(tmp.c_str(), path.c_str()) != 0) return errno_text(path + ": rename");
    // The rename itself is durable only once the directory is synced.
    std::filesystem::path dir = std::filesystem::path(path).parent_path();
    if (dir.empty()) dir = ".";
    const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd >= 0) {
        ::fsync(dfd);
        ::close(dfd);
    }
    return {};
}

modbus::Result<void, std::string> load_state(const std::string& path, const std::vector<Device*>& devices) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return {};  // first start: nothing saved yet
    json doc = json::parse(in, nullptr, false);
    if (doc.is_discarded())
        return path + ": not valid JSON (a damaged state file; remove it to start afresh)";
    // A string field, or "" when it is missing or of another type (json::value would throw on the latter).
    const auto text_of = [](const json& j, const char* key) {
        const auto it = j.is_object() ? j.find(key) : j.end();
        return it != j.end() && it->is_string() ? it->get<std::string>() : std::string();
    };
    if (text_of(doc, "format") != "mbscope-slave-state/1" || !doc.contains("units") ||
        !doc["units"].is_object())
        return path + ": not an mbscope slave state file (format mbscope-slave-state/1)";
    for (Device* d : devices) {
        const auto it = doc["units"].find(std::to_string(d->unit()));
        if (it == doc["units"].end()) continue;
        if (const auto saved = text_of(*it, "profile"); saved != d->profile().id)
            return path + ": unit " + std::to_string(d->unit()) + " was saved with profile \"" +
                   (saved.empty() ? "?" : saved) + "\", now served as \"" + d->profile().id + "\"";
        for (const auto& [name, values] : it->items()) {
            if (name == "profile") continue;
            const auto table = modbus::parse_table(name);
            if (!table || !values.is_object())
                return path + ": unit " + std::to_string(d->unit()) + ": unknown table \"" + name + "\"";
            for (const auto& [address, value] : values.items()) {
                char* end = nullptr;
                const unsigned long a = std::strtoul(address.c_str(), &end, 10);
                if (address.empty() || *end != '\0' || a > 65535 || !value.is_number_unsigned() ||
                    value.get<unsigned>() > 65535)
                    return path + ": unit " + std::to_string(d->unit()) + " " + name + "/" + address +
                           ": bad entry";
                d->image().set_reg(*table, static_cast<std::uint16_t>(a), value.get<std::uint16_t>());
            }
        }
    }
    return {};
}

}  // namespace mbscope::slave
