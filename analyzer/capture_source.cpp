#include "analyzer/capture_source.hpp"

#include <pcap/pcap.h>

#include <fcntl.h>
#include <poll.h>
#include <stdio_ext.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

#include "analyzer/pcapng_interfaces.hpp"
#include "analyzer/timestamps.hpp"

namespace mbscope::analyzer {

// What reads the file: libpcap and the bookkeeping of where each record ends. With read-ahead only the
// reading thread touches it.
struct CaptureSource::Impl {
    pcap_t* pcap = nullptr;
    int linktype = 0;
    // Classic pcap records are a fixed header and caplen bytes, so where the next one starts is known
    // without asking the FILE (ftell() was a twentieth of a summary run). record_header is learnt from the
    // first record (16 bytes, 24 in Kuznetzov's format); 0: ask ftell() after every record (pcapng).
    // position: where the last record read ends (-1: not known), so where the next one begins.
    long position = -1;
    long record_header = 0;
    std::uint64_t count = 0;
    modbus::Timestamp last_time{0};
    const PcapngInterfacePatch* interfaces = nullptr;  // the one its bytes pass through (the FILE's)
    bool one_pass_of_several = false;                  // of a pcapng file read once per link type
    std::optional<ReadFailure> failure;  // set when a record could not be read; reading ends there
    ~Impl() {
        if (pcap) pcap_close(pcap);  // closes the FILE too
    }
    // The next record: its data stay valid until the next call. False at the end or on damage (`failure`).
    bool read(Packet& packet, std::uint64_t& end_offset);
};

std::string CaptureSource::ReadFailure::message(const std::string& name, std::uint64_t packets) const {
    return interface_refused ? name + ": after " + std::to_string(packets) + " packets, " + what
                             : name + ": packet " + std::to_string(packets + 1) + what;
}

// Packets copied out of libpcap's buffer into batches by a reading thread, handed to next() a batch at a
// time through a ring of `depth` batches: one lock and, at most, one wake-up per batch, not per packet.
class CaptureSource::ReadAhead {
  public:
    explicit ReadAhead(Impl& impl) : impl_(impl), thread_([this] { run(); }) {}
    ~ReadAhead() {
        {
            std::lock_guard lock(mutex_);
            stop_ = true;
        }
        emptied_.notify_one();
        thread_.join();
    }
    ReadAhead(const ReadAhead&) = delete;
    ReadAhead& operator=(const ReadAhead&) = delete;

    // The next packet (its data valid until the next call), or nullopt at the end, with `failure` set when
    // the file was damaged, and `end_offset` where the packet ends in the file.
    std::optional<Packet> next(std::optional<ReadFailure>& failure, std::uint64_t& end_offset) {
        for (;;) {
            if (!current_) {
                std::unique_lock lock(mutex_);
                filled_.wait(lock, [this] { return produced_ > consumed_; });
                current_ = &batches_[consumed_ % depth];
                index_ = 0;
            }
            if (index_ < current_->records.size()) {
                const Record& r = current_->records[index_++];
                Packet p = r.packet;
                p.data = {current_->bytes.data() + r.data_at, r.data_length};
                end_offset = r.end_offset;
                return p;
            }
            if (current_->last) {
                failure = current_->failure;
                return std::nullopt;
            }
            {
                std::lock_guard lock(mutex_);
                ++consumed_;  // the batch goes back to the reader, its packets all handed out
            }
            emptied_.notify_one();
            current_ = nullptr;
        }
    }

  private:
    static constexpr std::size_t depth = 4;
    static constexpr std::size_t batch_packets = 1024;
    static constexpr std::size_t batch_bytes = 256 * 1024;
    struct Record {
        Packet packet;  // data: empty, see data_at
        std::size_t data_at = 0, data_length = 0;
        std::uint64_t end_offset = 0;
    };
    // A cache line each, and the consumer's state on its own: the reader grows one batch's lists packet by
    // packet while next() reads another's, and sharing a line made each packet a cache miss on both sides.
    struct alignas(64) Batch {
        std::vector<Record> records;
        std::vector<std::uint8_t> bytes;
        bool last = false;
        std::optional<ReadFailure> failure;
    };

    void run() {
        for (;;) {
            {
                std::unique_lock lock(mutex_);
                emptied_.wait(lock, [this] { return stop_ || produced_ - consumed_ < depth; });
                if (stop_) return;
            }
            Batch& b = batches_[produced_ % depth];  // free: neither side holds it
            b.records.clear();
            b.bytes.clear();
            Packet p;
            std::uint64_t end_offset = 0;
            while (b.records.size() < batch_packets && b.bytes.size() < batch_bytes) {
                if (!impl_.read(p, end_offset)) {
                    b.last = true;
                    b.failure = impl_.failure;
                    break;
                }
                Record r{p, b.bytes.size(), p.data.size(), end_offset};
                r.packet.data = {};
                b.bytes.insert(b.bytes.end(), p.data.begin(), p.data.end());
                b.records.push_back(r);
            }
            const bool last = b.last;
            {
                std::lock_guard lock(mutex_);
                ++produced_;
            }
            filled_.notify_one();
            if (last) return;
        }
    }

    Impl& impl_;
    std::array<Batch, depth> batches_;
    std::mutex mutex_;
    std::condition_variable filled_, emptied_;
    std::uint64_t produced_ = 0, consumed_ = 0;  // batches; guarded by mutex_
    bool stop_ = false;
    // the consumer's own
    alignas(64) Batch* current_ = nullptr;
    std::size_t index_ = 0;
    std::thread thread_;  // last: started once everything above is made
};

CaptureSource::~CaptureSource() {
    ahead_.reset();  // the reading thread ends before what it reads is closed
}

namespace {

// A file read through stdio whose position is known without a system call. The reader asks where it is
// before every packet (a damaged record is reported with its byte offset) and the progress line asks too;
// ftell() on an ordinary FILE is an lseek() each time, which was a sixth of the time of a summary run.
// Through fopencookie the position is our own count of the bytes read. On their way to libpcap the bytes
// of a pcapng file have their interfaces levelled (analyzer/pcapng_interfaces.hpp). A
// capture in memory (the fuzzer's, the tests') is read the same way.
struct CountedFile {
    int fd = -1;                             // a file's descriptor, or -1 for memory
    std::span<const std::uint8_t> memory{};  // fd -1: the capture
    // A stream: its first bytes, read before (to tell its format), come first; `stalled` is called when
    // the descriptor has nothing to read yet.
    std::vector<std::uint8_t> head;
    std::size_t head_given = 0;
    std::function<void()> stalled;
    off64_t position = 0;
    PcapngInterfacePatch interfaces;
    // stdio's buffer: glibc's setvbuf() ignores the size asked for unless it is given the buffer, and its
    // own is 8 KiB (a read() per 8 KiB: 5,000 system calls for a 40 MB capture). 64 KiB, not more: with
    // 256 KiB the read-ahead thread's copying out of the buffer took from one to two and a half times as
    // long from run to run (perf: glibc's copy loop; likely the buffer, filled by the kernel, no longer
    // sitting in the core's cache).
    static constexpr std::size_t buffer_size = 1 << 16;
    std::unique_ptr<char[]> buffer = std::make_unique_for_overwrite<char[]>(buffer_size);
};

// The next bytes of the source, counted and passed through the interface patch.
ssize_t read_source(CountedFile* f, char* buffer, std::size_t size) {
    ssize_t n;
    if (f->fd < 0) {
        const auto left =
            f->memory.size() - std::min<std::size_t>(static_cast<std::size_t>(f->position), f->memory.size());
        n = static_cast<ssize_t>(std::min(size, left));
        if (n > 0) std::memcpy(buffer, f->memory.data() + f->position, static_cast<std::size_t>(n));
    } else if (f->head_given < f->head.size()) {
        n = static_cast<ssize_t>(std::min(size, f->head.size() - f->head_given));
        std::memcpy(buffer, f->head.data() + f->head_given, static_cast<std::size_t>(n));
        f->head_given += static_cast<std::size_t>(n);
    } else {
        if (f->stalled) {
            pollfd ready{f->fd, POLLIN, 0};
            if (::poll(&ready, 1, 0) == 0) f->stalled();
        }
        do {
            n = ::read(f->fd, buffer, size);
        } while (n < 0 && errno == EINTR);
    }
    if (n > 0) {
        f->interfaces.pass({reinterpret_cast<std::uint8_t*>(buffer), static_cast<std::size_t>(n)});
        f->position += n;
    }
    return n;
}

// `n` bytes read into `buffer`, followed by the ones the interface patch wants to see before they are handed
// on (an interface's link type whole; a packet block's type with its interface), read right after them.
// When reading them fails while packets of other link types are being hidden, the read fails: one of them
// could otherwise reach libpcap.
ssize_t completed(CountedFile* f, char* buffer, ssize_t n) {
    while (n > 0) {
        const std::size_t wanted = f->interfaces.bytes_wanted();
        if (wanted == 0) break;
        const ssize_t more = read_source(f, buffer + n, wanted);
        if (more < 0 && f->interfaces.keeping()) return -1;
        if (more <= 0) break;  // the end (libpcap reports the block cut short), or the next read's error
        n += more;
    }
    return n;
}

ssize_t counted_read(void* cookie, char* buffer, std::size_t size) {
    auto* f = static_cast<CountedFile*>(cookie);
    f->interfaces.handed_on();
    // While a pcapng file's blocks are followed, room is kept at the end of the buffer for the bytes that
    // complete a header the read ends in (PcapngInterfacePatch::bytes_wanted). stdio asks for its buffer's
    // size (64 KiB) or a multiple of it, never less: a smaller read cannot keep a packet block from libpcap
    // when it must, and fails.
    constexpr std::size_t room = PcapngInterfacePatch::most_wanted;
    if (!f->interfaces.following()) return read_source(f, buffer, size);
    if (size <= room) {
        if (!f->interfaces.keeping()) return read_source(f, buffer, size);
        errno = EINVAL;
        return -1;
    }
    return completed(f, buffer, read_source(f, buffer, size - room));
}

int counted_seek(void* cookie, off64_t* offset, int whence) {
    auto* f = static_cast<CountedFile*>(cookie);
    if (whence == SEEK_CUR && *offset == 0) {  // ftell()
        *offset = f->position;
        return 0;
    }
    // The bytes no longer pass in file order. libpcap does not seek while it reads; damaged_block_offset
    // does once reading has ended.
    f->interfaces.stop();
    off64_t at;
    if (f->fd < 0) {
        const off64_t base = whence == SEEK_SET   ? 0
                             : whence == SEEK_CUR ? f->position
                                                  : static_cast<off64_t>(f->memory.size());
        at = base + *offset;
        if (at < 0) {
            errno = EINVAL;
            return -1;
        }
    } else {
        at = ::lseek64(f->fd, *offset, whence);
        if (at < 0) return -1;
    }
    f->position = *offset = at;
    return 0;
}

int counted_close(void* cookie) {
    auto* f = static_cast<CountedFile*>(cookie);
    const int rc = f->fd > STDIN_FILENO ? ::close(f->fd) : 0;
    delete f;
    return rc;
}

// Errors are the system's message alone: the caller names the file.
FILE* open_counted(CountedFile* cookie, std::string& error) {
    FILE* file = fopencookie(cookie, "rb", {counted_read, nullptr, counted_seek, counted_close});
    if (!file) {
        error = std::strerror(errno);
        counted_close(cookie);
        return nullptr;
    }
    std::setvbuf(file, cookie->buffer.get(), _IOFBF, CountedFile::buffer_size);  // freed by counted_close
    // One thread at a time reads the file (the read-ahead thread, or the caller): without this, glibc
    // locks the FILE for each of libpcap's two fread() calls a packet once the process has a second thread.
    __fsetlocking(file, FSETLOCKING_BYCALLER);
    return file;
}

// A cookie reading the file at `path` (or standard input for "-"); null with `error` when it cannot be
// opened.
CountedFile* file_cookie(const std::string& path, std::string& error) {
    const int fd = path == "-" ? STDIN_FILENO : ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        error = std::strerror(errno);
        return nullptr;
    }
    auto* cookie = new CountedFile;
    cookie->fd = fd;
    return cookie;
}

}  // namespace

namespace {

// libpcap reading `file` (null: not opened, `error` says why), or null with `error` naming `name`.
pcap_t* pcap_of(FILE* file, const std::string& name, std::string& error) {
    if (!file) {
        error = name + ": " + error;
        return nullptr;
    }
    char errbuf[PCAP_ERRBUF_SIZE] = {};
    pcap_t* p = pcap_fopen_offline_with_tstamp_precision(file, PCAP_TSTAMP_PRECISION_NANO, errbuf);
    if (!p) {
        std::fclose(file);
        error = name + ": " + errbuf;
    }
    return p;
}

}  // namespace

namespace {

// How much of a file's beginning is looked at for its interfaces: a capturing program describes them all
// before the first packet, in a few hundred bytes, or one before the first packet on it.
constexpr std::size_t interfaces_looked_for = 64 * 1024;

// The most passes a file is read in: each is a reading of the whole file and, for a file, a thread. A
// capture of more link types than this (none that a capturing program makes) is refused by libpcap at
// its first interface of another link type, as a stream is.
constexpr std::size_t most_passes = 8;

// The link types of a pcapng file's interfaces described in its first bytes (`head`, which the patch
// changes as it passes them): empty for classic pcap, damage, or more than most_passes.
std::vector<std::uint16_t> link_types_of(std::vector<std::uint8_t> head) {
    PcapngInterfacePatch scan;
    scan.pass(head);
    if (!scan.following() || scan.link_types().size() > most_passes) return {};
    return scan.link_types();
}

// Of a regular file. A FIFO or device is read once, as it comes, and not opened here: opening a FIFO waits
// for its writer, and closing it again could leave the writer without a reader for a moment.
std::vector<std::uint16_t> link_types_of_file(const std::string& path) {
    struct stat st {};
    if (path == "-" || ::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return {};
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return {};
    std::vector<std::uint8_t> head(interfaces_looked_for);
    ssize_t n;
    do {
        n = ::pread(fd, head.data(), head.size(), 0);
    } while (n < 0 && errno == EINTR);
    ::close(fd);
    if (n <= 0) return {};
    head.resize(static_cast<std::size_t>(n));
    return link_types_of(std::move(head));
}

}  // namespace

// `known` the file's link types: one pass for each if there are two or more, the file read once otherwise.
std::unique_ptr<CaptureSource> CaptureSource::opened(const Reopen& open,
                                                     const std::vector<std::uint16_t>& known,
                                                     std::string& error) {
    if (known.size() < 2) {
        auto s = open(0, {}, error);
        if (s) {
            s->reopen_ = open;
            s->known_ = known;
        }
        return s;
    }
    std::vector<std::unique_ptr<CaptureSource>> passes;
    for (const std::uint16_t type : known) {
        auto pass = open(type, known, error);
        if (!pass) return nullptr;
        passes.push_back(std::move(pass));
    }
    std::unique_ptr<CaptureSource> s(new CaptureSource);
    s->name_ = passes.front()->name_;
    s->linktype_ = passes.front()->linktype_;
    s->reopen_ = open;
    s->read_in_passes(std::move(passes), known);
    return s;
}

std::unique_ptr<CaptureSource> CaptureSource::open_file(const std::string& path, std::string& error,
                                                        const std::string& name) {
    const std::string shown = name.empty() ? path : name;
    const Reopen open = [path, shown](std::uint16_t kept, const std::vector<std::uint16_t>& known,
                                      std::string& error) -> std::unique_ptr<CaptureSource> {
        CountedFile* cookie = file_cookie(path, error);
        if (cookie && !known.empty()) cookie->interfaces.keep_only(kept, known);
        const PcapngInterfacePatch* interfaces = cookie ? &cookie->interfaces : nullptr;
        pcap_t* p = pcap_of(cookie ? open_counted(cookie, error) : nullptr, shown, error);
        return p ? made(p, shown, true, interfaces, !known.empty()) : nullptr;
    };
    return opened(open, link_types_of_file(path), error);
}

std::unique_ptr<CaptureSource> CaptureSource::open_memory(std::span<const std::uint8_t> bytes,
                                                          std::string& error) {
    if (bytes.empty()) {
        error = "memory: empty capture";
        return nullptr;
    }
    const Reopen open = [bytes](std::uint16_t kept, const std::vector<std::uint16_t>& known,
                                std::string& error) -> std::unique_ptr<CaptureSource> {
        auto* cookie = new CountedFile;
        cookie->memory = bytes;
        if (!known.empty()) cookie->interfaces.keep_only(kept, known);
        const PcapngInterfacePatch* interfaces = &cookie->interfaces;
        pcap_t* p = pcap_of(open_counted(cookie, error), "memory", error);
        return p ? made(p, "memory", false, interfaces, !known.empty()) : nullptr;
    };
    const auto head = bytes.first(std::min(bytes.size(), interfaces_looked_for));
    return opened(open, link_types_of(std::vector<std::uint8_t>(head.begin(), head.end())), error);
}

std::unique_ptr<CaptureSource> CaptureSource::open_stream(int fd, std::vector<std::uint8_t> head,
                                                          const std::string& name, std::string& error,
                                                          std::function<void()> stalled) {
    auto* cookie = new CountedFile;
    cookie->fd = fd;
    cookie->head = std::move(head);
    cookie->stalled = std::move(stalled);
    const PcapngInterfacePatch* interfaces = &cookie->interfaces;
    pcap_t* p = pcap_of(open_counted(cookie, error), name, error);
    return p ? made(p, name, false, interfaces, false) : nullptr;
}

std::unique_ptr<CaptureSource> CaptureSource::made(pcap_t* pcap, const std::string& name, bool read_ahead,
                                                   const PcapngInterfacePatch* interfaces,
                                                   bool one_pass_of_several) {
    std::unique_ptr<CaptureSource> s(new CaptureSource);
    s->impl_ = std::make_unique<Impl>();
    s->impl_->pcap = pcap;
    s->impl_->interfaces = interfaces;
    s->impl_->one_pass_of_several = one_pass_of_several;
    s->name_ = name;
    s->impl_->linktype = s->linktype_ = pcap_datalink(pcap);
    if (read_ahead) s->ahead_ = std::make_unique<ReadAhead>(*s->impl_);
    return s;
}

namespace {

std::uint32_t block_u32(const std::uint8_t* b, bool big_endian) {
    return big_endian ? std::uint32_t{b[0]} << 24 | b[1] << 16 | b[2] << 8 | b[3]
                      : std::uint32_t{b[3]} << 24 | b[2] << 16 | b[1] << 8 | b[0];
}

bool big_endian_file(pcap_t* pcap) {
    return (pcap_is_swapped(pcap) != 0) == (std::endian::native == std::endian::little);
}

// The pcapng block libpcap failed on, in a pass of a file read once per link type: that pass's last packet
// ended at `from`, and the blocks after it, hidden from it, may be other passes' packets, which come before
// the damage. libpcap stopped inside or at the end of the block it failed on (the file's end when it was cut
// short), so that is the block holding the byte before where the file stands. Reading ends here.
std::uint64_t damaged_block_offset(pcap_t* pcap, FILE* file, long from) {
    const long stop = file ? std::ftell(file) : -1;
    if (from < 0 || stop <= from) return from < 0 ? 0 : static_cast<std::uint64_t>(from);
    const bool big_endian = big_endian_file(pcap);
    long at = from;
    std::uint8_t b[8];
    while (std::fseek(file, at, SEEK_SET) == 0 && std::fread(b, 1, 8, file) == 8) {
        const std::uint32_t length = block_u32(b + 4, big_endian);
        if (length < 12 || length % 4 != 0 || at + static_cast<long>(length) >= stop) break;
        at += static_cast<long>(length);
    }
    return static_cast<std::uint64_t>(at);
}

}  // namespace

bool CaptureSource::Impl::read(Packet& packet, std::uint64_t& end_offset) {
    pcap_pkthdr* header = nullptr;
    const u_char* data = nullptr;
    FILE* file = pcap_file(pcap);
    const long before = count > 0 && position >= 0 ? position : file ? std::ftell(file) : -1;
    const int rc = pcap_next_ex(pcap, &header, &data);
    if (rc == 1 && file) {
        const long caplen = header->caplen;
        // A record longer than the snapshot length is cut to it by libpcap, which skips the rest: its size
        // on disk is not known from the header then, and ftell() says.
        const bool cut = caplen >= pcap_snapshot(pcap);
        if (record_header && !cut) {
            position = before + record_header + caplen;
        } else {
            position = std::ftell(file);
            const long header_size = position - before - caplen;
            if (count == 0 && pcap_major_version(pcap) == 2 && before >= 0 && !cut &&
                (header_size == 16 || header_size == 24))
                record_header = header_size;
        }
        end_offset = position > 0 ? static_cast<std::uint64_t>(position) : 0;
    }
    if (rc == 1) {
        packet.number = ++count;
        // Opened with nanosecond precision: tv_usec holds nanoseconds.
        const auto time = timestamp_from(header->ts.tv_sec, header->ts.tv_usec);
        packet.time_out_of_range = !time;
        packet.time = last_time = time.value_or(last_time);
        packet.linktype = linktype;
        packet.data = {data, header->caplen};
        packet.original_length = header->len;
        return true;
    }
    if (rc == PCAP_ERROR_BREAK) return false;  // end of file
    const std::string why = pcap_geterr(pcap);
    ReadFailure f;
    if (why.find("different from the type of the first interface") != std::string::npos) {
        // Not damage, and not a packet: an interface block libpcap will not take. The file is fine;
        // libpcap (1.10) reads pcapng only while every interface has the first one's link type.
        f.interface_refused = true;
        // The patch its bytes passed through saw that interface, and where it starts: also in a stream,
        // which cannot be moved back to look, and whatever blocks lie between the last packet and it.
        std::string at;
        if (interfaces) f.link_types = interfaces->link_types();
        if (interfaces && interfaces->refused_at()) {
            f.offset = *interfaces->refused_at();
            at = " at byte offset " + std::to_string(f.offset);
        }
        f.what =
            "an interface block" + at + ": " + why +
            "; libpcap reads pcapng only while all its interfaces share one link type, and a file (not a "
            "pipe) of up to 8 link types is read once for each: save it to a file, or split it by "
            "interface (tshark -r FILE -Y frame.interface_id==N -w PART.pcapng) and decode the parts "
            "together (they are merged by time)";
    } else {
        f.offset = one_pass_of_several ? damaged_block_offset(pcap, file, before)
                   : before >= 0       ? static_cast<std::uint64_t>(before)
                                       : 0;
        f.what = (before >= 0 ? " at byte offset " + std::to_string(f.offset) : "") + ": " + why;
    }
    failure = std::move(f);
    return false;
}

std::optional<Packet> CaptureSource::next() {
    if (!error_.empty()) return std::nullopt;
    if (!passes_.empty()) return next_of_passes();
    std::optional<Packet> p;
    if (ahead_) {
        p = ahead_->next(failure_, offset_);
    } else {
        p.emplace();
        if (!impl_->read(*p, offset_)) {
            p.reset();
            failure_ = impl_->failure;
        }
    }
    if (p) {
        ++count_;
        return p;
    }
    if (failure_ && read_again(*failure_)) return next_of_passes();
    if (failure_) error_ = failure_->message(name_, count_);
    return std::nullopt;
}

void CaptureSource::read_in_passes(std::vector<std::unique_ptr<CaptureSource>> passes,
                                   std::vector<std::uint16_t> known) {
    ahead_.reset();  // its thread ends before what it reads is closed
    impl_.reset();
    passes_.clear();
    for (auto& pass : passes)
        passes_.push_back(Pass{std::move(pass), std::nullopt, 0, false});
    known_ = std::move(known);
    failure_.reset();
}

// An interface of a link type the passes do not know was refused: read the file again in a pass for each
// link type met so far, the packets handed out already skipped. Not for a stream, nor beyond most_passes.
bool CaptureSource::read_again(const ReadFailure& failure) {
    if (!reopen_ || !failure.interface_refused) return false;
    std::vector<std::uint16_t> known = known_;
    for (const std::uint16_t type : failure.link_types)
        if (std::find(known.begin(), known.end(), type) == known.end()) known.push_back(type);
    if (known.size() < 2 || known.size() == known_.size() || known.size() > most_passes) return false;
    std::vector<std::unique_ptr<CaptureSource>> passes;
    for (const std::uint16_t type : known) {
        std::string error;
        auto pass = reopen_(type, known, error);
        if (!pass) return false;  // the refusal stands
        passes.push_back(std::move(pass));
    }
    read_in_passes(std::move(passes), std::move(known));
    skip_through_ = offset_;
    return true;
}

// The passes' next packets in the order they lie in the file, up to the first failure of any pass: the
// packets of the others that lie before the block it failed on come first, then reading ends, as it ends
// at the damage of a file read once (or the file is read again, when an interface of a new link type was
// refused). Packets ending at or before skip_through_ were handed out before the file was read again.
std::optional<Packet> CaptureSource::next_of_passes() {
    for (;;) {
        Pass* earliest = nullptr;
        const ReadFailure* failed = nullptr;
        for (Pass& pass : passes_) {
            if (!pass.packet && !pass.over) {
                pass.packet = pass.source->next();
                pass.end = pass.source->offset();
                pass.over = !pass.packet;
            }
            if (pass.packet && (!earliest || pass.end < earliest->end)) earliest = &pass;
            const auto& f = pass.source->failure_;
            if (pass.over && f && (!failed || f->offset < failed->offset)) failed = &*f;
        }
        if (failed && (!earliest || failed->offset < earliest->end)) {
            const ReadFailure failure = *failed;  // the passes may be replaced
            if (read_again(failure)) continue;
            failure_ = failure;
            error_ = failure_->message(name_, count_);
            return std::nullopt;
        }
        if (!earliest) return std::nullopt;
        // Its data stay valid until that pass is read again, on the next call.
        std::optional<Packet> p = std::exchange(earliest->packet, std::nullopt);
        if (earliest->end <= skip_through_) continue;
        p->number = ++count_;
        offset_ = earliest->end;
        return p;
    }
}

}  // namespace mbscope::analyzer
