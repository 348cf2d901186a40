#include "modbus/storage/text_file.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>

namespace mbscope::modbus::storage {

LineReader::LineReader(std::istream& in, std::size_t max_length) : in_(in), max_(max_length) {}

bool LineReader::next(std::string& line) {
    line.clear();
    too_long_ = false;
    length_ = 0;
    if (!in_.good()) return false;
    // The line is read a piece at a time: the string grows with the line up to the bound and no further
    // (a buffer of the bound's size made for every reader cost the serial-log fuzz target half its speed).
    for (bool first = true;; first = false) {
        in_.getline(piece_.data(), static_cast<std::streamsize>(piece_.size()));
        const auto got = static_cast<std::size_t>(in_.gcount());
        if (first && got == 0 && in_.eof()) return false;  // no line left
        // getline extracts and counts the LF; it stops with failbit when the piece is full and no LF
        // follows (the delimiter is looked for before the count), and with eofbit at the end of the input.
        const bool more = in_.fail() && !in_.eof() && !in_.bad() && got == piece_.size() - 1;
        if (in_.fail() && !more && !in_.eof()) return false;  // a read error
        const std::size_t chars = in_.eof() || more ? got : got - 1;
        length_ += chars;
        if (line.size() < max_) line.append(piece_.data(), std::min(chars, max_ - line.size()));
        if (!more) break;
        in_.clear();
    }
    if (in_.eof()) in_.clear(std::ios::eofbit);  // the line counts; the next call ends
    ++number_;
    too_long_ = length_ > max_;
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
        // A directory opens but cannot be read: say so rather than blame the disk.
        std::error_code ec;
        error = std::filesystem::is_directory(path, ec) ? "is a directory, not a file" : "read error";
        return std::nullopt;
    }
    return text;
}

}  // namespace mbscope::modbus::storage
