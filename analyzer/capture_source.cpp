#include "analyzer/capture_source.hpp"

#include <pcap/pcap.h>

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include "analyzer/timestamps.hpp"

namespace mbscope::analyzer {

struct CaptureSource::Impl {
    pcap_t* pcap = nullptr;
    // Classic pcap records are a fixed header and caplen bytes, so where the next one starts is known
    // without asking the FILE (ftell() was a twentieth of a summary run). record_header is learnt from the
    // first record (16 bytes, 24 in Kuznetzov's format); 0: ask ftell() before every record (pcapng).
    long position = -1;
    long record_header = 0;
    FILE* memory = nullptr;  // fmemopen'd buffer for open_memory
    ~Impl() {
        if (pcap) pcap_close(pcap);  // closes the FILE too
    }
};

CaptureSource::~CaptureSource() = default;

namespace {

// A file read through stdio whose position is known without a system call. The reader asks where it is
// before every packet (a damaged record is reported with its byte offset) and the progress line asks too;
// ftell() on an ordinary FILE is an lseek() each time, which was a sixth of the time of a summary run.
// Through fopencookie the position is our own count of the bytes read.
struct CountedFile {
    int fd = -1;
    off64_t position = 0;
    // stdio's buffer: glibc's setvbuf() ignores the size asked for unless it is given the buffer, and its
    // own is 8 KiB (a read() per 8 KiB: 5,000 system calls for a 40 MB capture).
    static constexpr std::size_t buffer_size = 1 << 18;
    std::unique_ptr<char[]> buffer = std::make_unique_for_overwrite<char[]>(buffer_size);
};

ssize_t counted_read(void* cookie, char* buffer, std::size_t size) {
    auto* f = static_cast<CountedFile*>(cookie);
    ssize_t n;
    do {
        n = ::read(f->fd, buffer, size);
    } while (n < 0 && errno == EINTR);
    if (n > 0) f->position += n;
    return n;
}

int counted_seek(void* cookie, off64_t* offset, int whence) {
    auto* f = static_cast<CountedFile*>(cookie);
    if (whence == SEEK_CUR && *offset == 0) {  // ftell()
        *offset = f->position;
        return 0;
    }
    const off64_t at = ::lseek64(f->fd, *offset, whence);
    if (at < 0) return -1;
    f->position = *offset = at;
    return 0;
}

int counted_close(void* cookie) {
    auto* f = static_cast<CountedFile*>(cookie);
    const int rc = f->fd > STDIN_FILENO ? ::close(f->fd) : 0;
    delete f;
    return rc;
}

FILE* open_counted(const std::string& path, std::string& error) {
    const int fd = path == "-" ? STDIN_FILENO : ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        error = path + ": " + std::strerror(errno);
        return nullptr;
    }
    auto* cookie = new CountedFile{fd, 0};
    FILE* file = fopencookie(cookie, "rb", {counted_read, nullptr, counted_seek, counted_close});
    if (!file) {
        error = path + ": " + std::strerror(errno);
        counted_close(cookie);
        return nullptr;
    }
    std::setvbuf(file, cookie->buffer.get(), _IOFBF, CountedFile::buffer_size);  // freed by counted_close
    return file;
}

}  // namespace

std::unique_ptr<CaptureSource> CaptureSource::open_file(const std::string& path, std::string& error) {
    FILE* file = open_counted(path, error);
    if (!file) return nullptr;
    char errbuf[PCAP_ERRBUF_SIZE] = {};
    pcap_t* p = pcap_fopen_offline_with_tstamp_precision(file, PCAP_TSTAMP_PRECISION_NANO, errbuf);
    if (!p) {
        std::fclose(file);
        error = path + ": " + errbuf;
        return nullptr;
    }
    std::unique_ptr<CaptureSource> s(new CaptureSource);
    s->impl_ = std::make_unique<Impl>();
    s->impl_->pcap = p;
    s->name_ = path;
    return s;
}

std::unique_ptr<CaptureSource> CaptureSource::open_memory(std::span<const std::uint8_t> bytes,
                                                          std::string& error) {
    if (bytes.empty()) {
        error = "memory: empty capture";
        return nullptr;
    }
    FILE* f = fmemopen(const_cast<std::uint8_t*>(bytes.data()), bytes.size(), "rb");
    if (!f) {
        error = "memory: cannot open";
        return nullptr;
    }
    char errbuf[PCAP_ERRBUF_SIZE] = {};
    pcap_t* p = pcap_fopen_offline_with_tstamp_precision(f, PCAP_TSTAMP_PRECISION_NANO, errbuf);
    if (!p) {
        fclose(f);
        error = std::string("memory: ") + errbuf;
        return nullptr;
    }
    std::unique_ptr<CaptureSource> s(new CaptureSource);
    s->impl_ = std::make_unique<Impl>();
    s->impl_->pcap = p;
    s->name_ = "memory";
    return s;
}

int CaptureSource::linktype() const noexcept {
    return pcap_datalink(impl_->pcap);
}

std::uint64_t CaptureSource::offset() const noexcept {
    FILE* file = pcap_file(impl_->pcap);
    const long at = file ? std::ftell(file) : -1;
    return at > 0 ? static_cast<std::uint64_t>(at) : 0;
}

std::optional<Packet> CaptureSource::next() {
    if (!error_.empty()) return std::nullopt;
    pcap_pkthdr* header = nullptr;
    const u_char* data = nullptr;
    FILE* file = pcap_file(impl_->pcap);
    const long before = impl_->record_header ? impl_->position : file ? std::ftell(file) : -1;
    const int rc = pcap_next_ex(impl_->pcap, &header, &data);
    if (rc == 1 && file) {
        const long caplen = header->caplen;
        // A record longer than the snapshot length is cut to it by libpcap, which skips the rest: its size
        // on disk is not known from the header then, and ftell() says.
        const bool cut = caplen >= pcap_snapshot(impl_->pcap);
        if (impl_->record_header && !cut) {
            impl_->position = before + impl_->record_header + caplen;
        } else if (count_ == 0 && pcap_major_version(impl_->pcap) == 2 && before >= 0 && !cut) {
            const long after = std::ftell(file);
            if (after - before - caplen == 16 || after - before - caplen == 24) {
                impl_->record_header = after - before - caplen;
                impl_->position = after;
            }
        } else if (impl_->record_header) {
            impl_->position = std::ftell(file);
        }
    }
    if (rc == 1) {
        Packet p;
        p.number = ++count_;
        // Opened with nanosecond precision: tv_usec holds nanoseconds.
        const auto time = timestamp_from(header->ts.tv_sec, header->ts.tv_usec);
        p.time_out_of_range = !time;
        p.time = last_time_ = time.value_or(last_time_);
        p.linktype = pcap_datalink(impl_->pcap);
        p.data = {data, header->caplen};
        p.original_length = header->len;
        return p;
    }
    if (rc == PCAP_ERROR_BREAK) return std::nullopt;  // end of file
    error_ = name_ + ": packet " + std::to_string(count_ + 1) +
             (before >= 0 ? " at byte offset " + std::to_string(before) : "") + ": " +
             pcap_geterr(impl_->pcap);
    return std::nullopt;
}

}  // namespace mbscope::analyzer
