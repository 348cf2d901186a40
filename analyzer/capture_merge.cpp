#include "analyzer/capture_merge.hpp"

#include <algorithm>

namespace mbscope::analyzer {

struct CaptureMerge::Member {
    CaptureFile file;
    std::size_t order = 0;  // its place among the files named: breaks ties between equal times
    // Its first packet's time; the earliest time there is when it has none to read (empty, or damaged at
    // the start): such a file is opened first, and its error is reported before the others' packets.
    modbus::Timestamp first = modbus::Timestamp::min();
    std::unique_ptr<CaptureSource> source;  // while open
    std::optional<Packet> head;             // its next packet, not yet handed out
};

CaptureMerge::CaptureMerge(std::vector<CaptureFile> files) {
    members_.resize(files.size());
    for (std::size_t i = 0; i < files.size(); ++i) {
        Member& m = members_[i];
        m.file = std::move(files[i]);
        if (m.file.name.empty()) m.file.name = m.file.path;
        m.order = i;
        by_first_.push_back(i);
        if (files.size() == 1) continue;  // nothing to order: no need to read its first packet twice
        std::string ignored;              // met again, and reported, when the file is opened to be read
        if (auto peek = CaptureSource::open_file(m.file.path, ignored, m.file.name))
            if (auto p = peek->next()) m.first = p->time;
    }
    std::stable_sort(by_first_.begin(), by_first_.end(),
                     [this](std::size_t a, std::size_t b) { return members_[a].first < members_[b].first; });
}

CaptureMerge::~CaptureMerge() = default;

std::optional<Packet> CaptureMerge::next() {
    if (last_) advance(*last_);  // only now: the packet handed out last lives in its file's buffer
    last_ = nullptr;
    admit();
    for (std::size_t i : active_) {
        Member& m = members_[i];
        if (!last_ || m.head->time < last_->head->time ||
            (m.head->time == last_->head->time && m.order < last_->order))
            last_ = &m;
    }
    if (!last_) return std::nullopt;
    return last_->head;
}

// Opens the files whose first packet is not later than the earliest packet at hand (all of the next ones
// while none is at hand), so that a file enters the merge before any packet later than its first.
void CaptureMerge::admit() {
    while (admitted_ < by_first_.size()) {
        Member& m = members_[by_first_[admitted_]];
        if (!active_.empty()) {
            const auto earliest =
                std::min_element(active_.begin(), active_.end(), [this](std::size_t a, std::size_t b) {
                    return members_[a].head->time < members_[b].head->time;
                });
            if (m.first > members_[*earliest].head->time) break;
        }
        ++admitted_;
        open(m);
    }
}

void CaptureMerge::open(Member& m) {
    std::string error;
    m.source = CaptureSource::open_file(m.file.path, error, m.file.name);
    if (!m.source) {
        errors_.push_back(error);
        return;
    }
    active_.push_back(m.order);
    m.head = m.source->next();
    if (m.head) return;
    // A file header and nothing after it, as a capture read alone says (Analyzer::read_capture).
    const bool damaged = !m.source->error().empty();
    close(m);
    if (!damaged) errors_.push_back(m.file.name + ": the capture holds no packets, nothing to decode");
}

void CaptureMerge::advance(Member& m) {
    m.head = m.source->next();
    if (!m.head) close(m);
}

void CaptureMerge::close(Member& m) {
    if (!m.source->error().empty()) errors_.push_back(m.source->error());
    closed_bytes_ += m.source->offset();
    m.source.reset();
    std::erase(active_, m.order);
}

const std::string& CaptureMerge::name() const noexcept {
    static const std::string none;
    return last_ ? last_->file.name : none;
}

std::uint64_t CaptureMerge::offset() const noexcept {
    std::uint64_t bytes = closed_bytes_;
    for (std::size_t i : active_)
        bytes += members_[i].source->offset();
    return bytes;
}

std::size_t CaptureMerge::files_open() const noexcept {
    return static_cast<std::size_t>(
        std::count_if(members_.begin(), members_.end(), [](const Member& m) { return m.source != nullptr; }));
}

}  // namespace mbscope::analyzer
