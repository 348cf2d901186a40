#include "modbus/storage/text_file.hpp"

#include <fstream>

namespace mbscope::modbus::storage {

LineReader::LineReader(std::istream& in, std::size_t max_length)
    : in_(in), max_(max_length), buffer_(max_length + 1) {}

bool LineReader::next(std::string& line) {
    line.clear();
    too_long_ = false;
    length_ = 0;
    if (!in_.good()) return false;
    // istream::getline stores at most max_ characters; a line of exactly max_ followed by LF is taken whole
    // (the delimiter is looked for before the count), a longer one stops with failbit.
    in_.getline(buffer_.data(), static_cast<std::streamsize>(buffer_.size()));
    const auto got = static_cast<std::size_t>(in_.gcount());
    if (got == 0 && in_.eof()) return false;
    const bool hit_bound = in_.fail() && !in_.eof() && !in_.bad() && got == max_;
    if (in_.fail() && !hit_bound) return false;  // a read error, or nothing extracted
    ++number_;
    if (hit_bound) {
        line.assign(buffer_.data(), got);
        too_long_ = true;
        length_ = got;
        in_.clear();
        // Read past the rest of the line a bounded piece at a time, counting it.
        for (;;) {
            in_.getline(buffer_.data(), static_cast<std::streamsize>(buffer_.size()));
            const auto more = static_cast<std::size_t>(in_.gcount());
            if (in_.eof() || in_.bad()) {  // the input ends inside the line
                length_ += more;
                break;
            }
            if (in_.fail()) {  // another max_ characters and still no LF
                in_.clear();
                length_ += more;
                continue;
            }
            length_ += more - 1;  // up to and with the LF
            break;
        }
        return true;
    }
    // The LF was extracted and counted by gcount; at the end of the input without one it was not.
    const std::size_t n = in_.eof() ? got : got - 1;
    line.assign(buffer_.data(), n);
    length_ = n;
    if (in_.eof()) in_.clear(std::ios::eofbit);
    return true;
}

std::string too_long_line_message(const LineReader& reader) {
    return "line of " + std::to_string(reader.length()) + " bytes is longer than the " +
           std::to_string(reader.max_length()) + " a line may hold: skipped";
}

std::optional<std::string> read_text_file(const std::string& path, std::string& error, std::uintmax_t limit) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        error = "cannot open";
        return std::nullopt;
    }
    std::string text;
    char buffer[65536];
    while (in) {
        in.read(buffer, sizeof buffer);
        const auto n = static_cast<std::size_t>(in.gcount());
        if (text.size() + n > limit) {
            error =
                "larger than " + std::to_string(limit) + " bytes, the most a document may hold (not read)";
            return std::nullopt;
        }
        text.append(buffer, n);
    }
    if (in.bad()) {
        error = "read error";
        return std::nullopt;
    }
    return text;
}

}  // namespace mbscope::modbus::storage
