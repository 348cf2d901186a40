#pragma once
// Several capture files read as one capture, packet by packet in time order, as mergecap merges them: the
// next packet is the earliest of the files' next ones (on equal times, the file named first), and each
// file keeps its own order even where its clock goes back. So the parts of a ring buffer named in any order,
// the two directions of a tap recorded on two interfaces, or captures from different days read as one
// timeline: a request in one file pairs with its response in another, and a file whose times come before
// the last one's does not make every request of it look unanswered.
//
// Files are opened when the merge reaches their first packet and closed at their end (their first packets'
// times are read once beforehand), so a ring buffer of a thousand parts holds one or two files open, not a
// thousand descriptors and read-ahead threads.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "analyzer/capture_source.hpp"

namespace mbscope::analyzer {

struct CaptureFile {
    std::string path;  // where to open it
    std::string name;  // what its packets and errors are named after (the path when empty)
};

class CaptureMerge {
  public:
    explicit CaptureMerge(std::vector<CaptureFile> files);
    ~CaptureMerge();
    CaptureMerge(const CaptureMerge&) = delete;
    CaptureMerge& operator=(const CaptureMerge&) = delete;

    // The next packet of the merged capture (its data valid until the next call; its number is its place in
    // its own file), or nullopt when every file is read to its end or to its damage.
    std::optional<Packet> next();
    // The name of the file the last packet came from.
    const std::string& name() const noexcept;
    // Bytes read so far, over all the files.
    std::uint64_t offset() const noexcept;
    // Files that could not be opened or were damaged, each with where (CaptureSource's messages), in the
    // order they were met. Everything before a file's damage was still merged.
    const std::vector<std::string>& errors() const noexcept { return errors_; }
    // Files open at this moment (for the tests: a long ring buffer must not hold them all).
    std::size_t files_open() const noexcept;

  private:
    struct Member;
    void admit();
    void open(Member& m);
    void advance(Member& m);
    void close(Member& m);

    std::vector<Member> members_;        // in the order the files were named
    std::vector<std::size_t> by_first_;  // members by their first packet's time (then the order named)
    std::size_t admitted_ = 0;           // by_first_'s members opened so far
    std::vector<std::size_t> active_;    // members open with a packet at hand
    Member* last_ = nullptr;             // whose packet next() handed out last
    std::uint64_t closed_bytes_ = 0;     // bytes of the files read to their end
    std::vector<std::string> errors_;
};

}  // namespace mbscope::analyzer
