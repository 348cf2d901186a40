#include "analyzer/capture_source.hpp"

#include <pcap/pcap.h>

#include <cstdio>

#include "analyzer/timestamps.hpp"

namespace mbscope::analyzer {

struct CaptureSource::Impl {
    pcap_t* pcap = nullptr;
    FILE* memory = nullptr;  // fmemopen'd buffer for open_memory
    ~Impl() {
        if (pcap) pcap_close(pcap);  // closes the FILE too
    }
};

CaptureSource::~CaptureSource() = default;

std::unique_ptr<CaptureSource> CaptureSource::open_file(const std::string& path, std::string& error) {
    char errbuf[PCAP_ERRBUF_SIZE] = {};
    pcap_t* p = pcap_open_offline_with_tstamp_precision(path.c_str(), PCAP_TSTAMP_PRECISION_NANO, errbuf);
    if (!p) {
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
    const long before = file ? std::ftell(file) : -1;
    const int rc = pcap_next_ex(impl_->pcap, &header, &data);
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
