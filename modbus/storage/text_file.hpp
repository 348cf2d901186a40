#pragma once
// Text files read with bounds. Whatever a user points mbscope at may be damaged or hostile: a log without a
// newline, or a "profile" of gigabytes, must be an error that names the file and the line, not one string
// the size of the file (a line reader that grows its string until the newline it never meets runs the
// machine out of memory).

#include <array>
#include <cstdint>
#include <istream>
#include <optional>
#include <string>

namespace mbscope::modbus::storage {

// The longest line a log or capture text may hold: socat and jpnevulator write 16 bytes a line, the text
// format one chunk of bytes a line (a megabyte holds over 300,000 of them).
inline constexpr std::size_t max_line_length = std::size_t{1} << 20;
// The largest JSON document (profile, maps file, state file, reproducer) or frames file read whole. The
// bundled profiles are under 200 KB, a slave's state with every table full about 10 MB.
inline constexpr std::uintmax_t max_document_size = std::uintmax_t{64} << 20;

class LineReader {
  public:
    explicit LineReader(std::istream& in, std::size_t max_length = max_line_length);

    // The next line without its LF into `line`; false at the end of the input. A line longer than the bound
    // is cut to it (too_long(), length() gives its whole length) and the rest of it is read past, so the
    // next call returns the line after it.
    bool next(std::string& line);
    std::uint64_t number() const noexcept { return number_; }  // 1-based number of the last line returned
    bool too_long() const noexcept { return too_long_; }
    std::uint64_t length() const noexcept { return length_; }
    std::size_t max_length() const noexcept { return max_; }

  private:
    std::istream& in_;
    std::size_t max_;
    std::array<char, 4096> piece_;
    std::uint64_t number_ = 0;
    std::uint64_t length_ = 0;
    bool too_long_ = false;
};

// "line of 5,000,000 bytes is longer than the 1,048,576 a line may hold: skipped"
std::string too_long_line_message(const LineReader& reader);

// A whole file as text; nullopt with `error` set ("cannot open", "larger than ... bytes, the most a
// document may hold") when it cannot be read or is larger than `limit`. The caller names the file.
std::optional<std::string> read_text_file(const std::string& path, std::string& error,
                                          std::uintmax_t limit = max_document_size);

}  // namespace mbscope::modbus::storage
