#include "slave/state_file.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "modbus/frame_text.hpp"  // printable()
#include "modbus/storage/text_file.hpp"

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

std::string state_text(const std::vector<Device*>& devices, const OtherUnits& others) {
    json doc{{"format", "mbscope-slave-state/1"}, {"units", others.is_object() ? others : json::object()}};
    for (const Device* d : devices) {
        json unit{{"profile", d->profile().id}};
        for (const auto& [table, values] : d->image().changes()) {
            json t = json::object();
            for (const auto& [address, value] : values)
                t[std::to_string(address)] = value;
            unit[std::string(modbus::to_string(table))] = std::move(t);
        }
        doc["units"][std::to_string(d->configured_unit())] = std::move(unit);
    }
    return doc.dump(1) + "\n";
}

modbus::Result<void, std::string> save_state(const std::string& path, const std::vector<Device*>& devices,
                                             const OtherUnits& others) {
    const std::string data = state_text(devices, others);
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

modbus::Result<modbus::transport::UniqueFd, std::string> lock_state(const std::string& path) {
    const std::string lock = path + ".lock";
    // Read-only is enough for flock, and 0666 (less the umask): a lock file left by one user must not stop
    // another who may write the state file from taking it.
    modbus::transport::UniqueFd fd(::open(lock.c_str(), O_RDONLY | O_CREAT | O_CLOEXEC, 0666));
    if (fd.get() < 0) return errno_text(lock + ": open");
    if (::flock(fd.get(), LOCK_EX | LOCK_NB) != 0) {
        if (errno == EWOULDBLOCK)
            return path + ": in use by another mbscope slave (it holds " + lock +
                   "); two slaves saving one state file would each write back their own view of it and lose "
                   "the writes the other acknowledged";
        return errno_text(lock + ": flock");
    }
    return fd;
}

modbus::Result<OtherUnits, std::string> load_state(const std::string& path,
                                                   const std::vector<Device*>& devices) {
    // Not blocking: a FIFO or a device would hold the start forever (open waits for a writer) before a
    // word is said.
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd < 0) {
        if (errno == ENOENT) return OtherUnits{};  // first start: nothing saved yet
        // Not a first start: starting afresh would overwrite the saved image at the first write.
        return errno_text(path + ": open");
    }
    struct stat st {};
    if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        ::close(fd);
        return path + ": not a regular file (a state file is one, written by mbscope slave)";
    }
    std::string text;
    char buffer[65536];
    for (;;) {
        const ssize_t n = ::read(fd, buffer, sizeof buffer);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) {
            const auto error = errno_text(path + ": read");
            ::close(fd);
            return error;
        }
        if (n == 0) break;
        if (text.size() + static_cast<std::size_t>(n) > modbus::storage::max_document_size) {
            ::close(fd);
            return path + ": larger than " + std::to_string(modbus::storage::max_document_size) +
                   " bytes, the most a state file may hold (not a state file; remove it to start afresh)";
        }
        text.append(buffer, static_cast<std::size_t>(n));
    }
    ::close(fd);
    return apply_state(text, path, devices);
}

modbus::Result<OtherUnits, std::string> apply_state(std::string_view text, const std::string& name,
                                                    const std::vector<Device*>& devices) {
    const json doc = json::parse(text.begin(), text.end(), nullptr, false);
    if (doc.is_discarded())
        return name + ": not valid JSON (a damaged state file; remove it to start afresh)";
    // A string field, or "" when it is missing or of another type (json::value would throw on the latter).
    const auto text_of = [](const json& j, const char* key) {
        const auto it = j.is_object() ? j.find(key) : j.end();
        return it != j.end() && it->is_string() ? it->get<std::string>() : std::string();
    };
    if (text_of(doc, "format") != "mbscope-slave-state/1" || !doc.contains("units") ||
        !doc["units"].is_object())
        return name + ": not an mbscope slave state file (format mbscope-slave-state/1)";
    struct Entry {
        Device* device;
        modbus::Table table;
        std::uint16_t address, value;
    };
    std::vector<Entry> entries;
    for (Device* d : devices) {
        const auto it = doc["units"].find(std::to_string(d->configured_unit()));
        if (it == doc["units"].end()) continue;
        const std::string unit = name + ": unit " + std::to_string(d->configured_unit());
        if (!it->is_object())
            return unit + ": not an object of the unit's profile and tables (" +
                   std::string(it->type_name()) + ")";
        if (const auto saved = text_of(*it, "profile"); saved != d->profile().id)
            return unit + " was saved with profile \"" + (saved.empty() ? "?" : modbus::printable(saved)) +
                   "\", now served as \"" + d->profile().id + "\"";
        for (const auto& [table_name, values] : it->items()) {
            if (table_name == "profile") continue;
            const auto table = modbus::parse_table(table_name);
            if (!table) return unit + ": unknown table \"" + modbus::printable(table_name) + "\"";
            if (!values.is_object())
                return unit + " " + modbus::printable(table_name) + ": not an object of address → value (" +
                       std::string(values.type_name()) + ")";
            // A coil or discrete input holds 0 or 1 (the slave saves bits so, also where they are views of
            // registers: it saves those as the registers).
            const unsigned most = modbus::is_bit_table(*table) ? 1 : 65535;
            for (const auto& [address, value] : values.items()) {
                char* end = nullptr;
                const unsigned long a = std::strtoul(address.c_str(), &end, 10);
                if (address.empty() || address.front() < '0' || address.front() > '9' || *end != '\0' ||
                    a > 65535 || !value.is_number_unsigned() || value.get<std::uint64_t>() > most)
                    return unit + " " + table_name + "/" + modbus::printable(address) + ": bad entry";
                entries.push_back({d, *table, static_cast<std::uint16_t>(a), value.get<std::uint16_t>()});
            }
        }
    }
    // What the map makes impossible a file may still hold (edited by hand, or from a map since corrected): a
    // fixed value that is not, or a writable point's value no write could have left (an address register
    // at 300 where the manual allows 0..99, a code no enumeration lists). Served, it would make the slave
    // answer what the device cannot; refused, the file names it. Read-only points hold what the process model
    // made them. A slave planted with accept-out-of-range took such values itself.
    for (const Entry& e : entries) {
        const modbus::Profile& p = e.device->profile();
        if (p.open_address_space || e.device->faults().enabled(Fault::AcceptOutOfRange)) continue;
        const std::string where = name + ": unit " + std::to_string(e.device->configured_unit()) + " " +
                                  std::string(modbus::to_string(e.table)) + "/" + std::to_string(e.address) +
                                  ": " + std::to_string(e.value);
        const auto* point = p.find(e.table, e.address);
        if (!point) return where + ", an address the map of " + p.id + " does not have";
        if (point->fixed_value && e.value != *point->fixed_value)
            return where + ", where the map fixes " + std::to_string(*point->fixed_value);
        if (point->access == modbus::Access::Read || point->reserved) continue;
        if (const auto r = modbus::check_writes(p, e.table, e.address, {e.value}))
            return where + ", which the map does not allow (" + r->reason + ")";
    }
    OtherUnits others = doc["units"];
    for (const Device* d : devices)
        others.erase(std::to_string(d->configured_unit()));
    for (const Entry& e : entries)
        e.device->image().set_reg(e.table, e.address, e.value);
    // A device whose address was written answers at it after a restart too, as one keeps it in its memory.
    for (Device* d : devices)
        d->follow_address();
    return others.empty() ? OtherUnits{} : others;
}

}  // namespace mbscope::slave
