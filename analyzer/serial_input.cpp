#include "analyzer/serial_input.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "analyzer/serial_logs.hpp"
#include "analyzer/timestamps.hpp"
#include "modbus/adu.hpp"         // rtu_crc_ok()
#include "modbus/describe.hpp"    // hex_bytes()
#include "modbus/frame_text.hpp"  // parse_hex(), quote_excerpt()
#include "modbus/storage/text_file.hpp"
#include "modbus/transport/unique_fd.hpp"

namespace mbscope::analyzer {

namespace transport = modbus::transport;
using modbus::Direction;

std::optional<InputFormat> parse_input_format(std::string_view n) {
    if (n == "auto") return InputFormat::Auto;
    if (n == "pcap" || n == "pcapng") return InputFormat::Pcap;
    if (n == "rtu" || n == "raw") return InputFormat::RtuRaw;
    if (n == "ascii") return InputFormat::AsciiRaw;
    if (n == "text") return InputFormat::Text;
    if (n == "jpnevulator") return InputFormat::Jpnevulator;
    if (n == "socat") return InputFormat::Socat;
    if (n == "hex") return InputFormat::Hex;
    return std::nullopt;
}

namespace {

bool parse_time(const std::string& token, modbus::Timestamp& t) {
    double seconds = 0;
    auto [p, ec] = std::from_chars(token.data(), token.data() + token.size(), seconds);
    if (ec != std::errc() || p != token.data() + token.size()) return false;
    const auto converted = timestamp_from_seconds(seconds);  // "1e300", "nan" and "inf" parse as doubles
    if (!converted) return false;
    t = *converted;
    return true;
}

// Tells the analyzer where `in` has got to, every `every` records: a progress line for serial logs moves
// within a file, not only from one file to the next.
class Position {
  public:
    Position(Analyzer& a, std::istream& in) : a_(a), in_(in) {}
    void record() {
        if (++count_ % every != 0) return;
        if (const auto at = in_.tellg(); at >= 0) a_.reached(static_cast<std::uint64_t>(at));
    }

  private:
    static constexpr std::uint64_t every = 1024;
    Analyzer& a_;
    std::istream& in_;
    std::uint64_t count_ = 0;
};

// An input to read: where to open it, and what to call it in records and errors.
struct Input {
    std::string path;
    std::string name;
    transport::UniqueFd spool;  // the temporary copy `path` opens, for a pipe or standard input
    // A capture read as it comes from a pipe or standard input (not copied first): the descriptor, and
    // its first bytes, read to tell that it is one.
    transport::UniqueFd stream;
    std::vector<std::uint8_t> head;
};

// A pipe, FIFO or socket (and "-", standard input) can be read once only, while reading an input opens it
// more than once: its head tells its format, an empty file is refused, a socat log is read twice. Such an
// input is copied first to a temporary file, unlinked at once (it goes when the descriptor closes, however
// the process ends), and read through /proc/self/fd under its own name. Regular files and devices are read
// where they are. A pcap or pcapng capture (its magic number) is the exception when `may_stream`: libpcap
// reads it once, front to back, so it is read as it comes (`tcpdump -U -w - | mbscope decode -`, a capture
// on another host through ssh), not after its writer has ended.
std::optional<Input> open_input(const std::string& name, std::string& error, bool may_stream) {
    struct stat st {};
    if (name != "-" && (::stat(name.c_str(), &st) != 0 || !(S_ISFIFO(st.st_mode) || S_ISSOCK(st.st_mode))))
        return Input{name, name, {}, {}, {}};
    transport::UniqueFd source(name == "-" ? ::dup(STDIN_FILENO)
                                           : ::open(name.c_str(), O_RDONLY | O_CLOEXEC));
    if (!source) {
        error = name + ": " + std::strerror(errno);
        return std::nullopt;
    }
    std::vector<char> buffer(1 << 16);
    std::size_t head = 0;  // the first bytes, up to a magic number's four
    while (may_stream && head < 4) {
        const ssize_t n = ::read(source.get(), buffer.data() + head, 4 - head);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) break;  // an error or the end: the copy below meets it again
        head += static_cast<std::size_t>(n);
    }
    const std::span<const std::uint8_t> first(reinterpret_cast<const std::uint8_t*>(buffer.data()), head);
    if (head == 4 && detect_input_format(first) == InputFormat::Pcap)
        return Input{name, name, {}, std::move(source), {first.begin(), first.end()}};
    std::string temporary = (std::filesystem::temp_directory_path() / "mbscope-input-XXXXXX").string();
    transport::UniqueFd spool(::mkstemp(temporary.data()));
    if (!spool) {
        error = name + ": cannot make a temporary copy in " + temporary + ": " + std::strerror(errno);
        return std::nullopt;
    }
    ::unlink(temporary.c_str());
    for (std::size_t n = head; n > 0;) {  // the bytes read to tell a capture, first
        const ssize_t w = ::write(spool.get(), buffer.data() + (head - n), n);
        if (w < 0 && errno == EINTR) continue;
        if (w < 0) {
            error = name + ": cannot make a temporary copy: " + std::strerror(errno);
            return std::nullopt;
        }
        n -= static_cast<std::size_t>(w);
    }
    for (;;) {
        const ssize_t n = ::read(source.get(), buffer.data(), buffer.size());
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) {
            error = name + ": " + std::strerror(errno);
            return std::nullopt;
        }
        if (n == 0) break;
        for (ssize_t done = 0; done < n;) {
            const ssize_t w = ::write(spool.get(), buffer.data() + done, static_cast<std::size_t>(n - done));
            if (w < 0 && errno == EINTR) continue;
            if (w < 0) {
                error = name + ": cannot make a temporary copy: " + std::strerror(errno);
                return std::nullopt;
            }
            done += w;
        }
    }
    const std::string path = "/proc/self/fd/" + std::to_string(spool.get());
    return Input{path, name, std::move(spool), {}, {}};
}

// The readers add to `bytes` every data byte they hand the analyzer, so that an input that held none is
// told from a quiet line.
//
// The text format, "TIME [DIR] HEX..." a line; with `timed` false a hex dump without times ("01 03 00 00 00
// 01 84 0A" a line, as traffic is pasted from a terminal or a page): its bytes one untimed stream, as a raw
// dump's, the lines' ends meaning nothing. '#' starts a comment, to the line's end.
bool read_text(Analyzer& a, const Input& input, std::uint64_t& bytes, bool timed) {
    const std::string& path = input.name;
    std::ifstream in(input.path);
    if (!in) {
        a.input_error(path + ": cannot open");
        return false;
    }
    bool ok = true;
    Position position(a, in);
    modbus::storage::LineReader lines(in);
    const auto error = [&](const std::string& message) { a.input_error(message); };
    for (std::string line; next_log_line(lines, line, path, error, ok);) {
        const auto number = lines.number();
        position.record();
        std::istringstream words(line);
        modbus::Timestamp t{0};
        std::optional<Direction> dir;
        std::vector<std::string> tokens;
        if (timed) {
            std::string time_token;
            if (!(words >> time_token) || time_token[0] == '#') continue;
            if (!parse_time(time_token, t)) {
                // A file of frames (`mbscope frame --file`: "rtu|ascii|tcp HEX...") starts its lines with a
                // framing.
                const bool frame_file = time_token == "rtu" || time_token == "ascii" || time_token == "tcp";
                a.input_error(
                    path + ":" + std::to_string(number) +
                    ": not a time in seconds from 0 to 9.2e9 (year 2262): " +
                    modbus::quote_excerpt(time_token) +
                    (frame_file ? " (a file of frames, one a line: mbscope frame --file reads it)" : ""));
                ok = false;
                continue;
            }
            std::string next;
            words >> next;
            dir = direction_word(next);
            if (!dir && !next.empty() && next[0] != '#') tokens.push_back(std::move(next));
        }
        for (std::string token; (tokens.empty() || tokens.back()[0] != '#') && words >> token;)
            tokens.push_back(std::move(token));
        if (!tokens.empty() && tokens.back()[0] == '#') tokens.pop_back();
        if (!timed && tokens.empty()) continue;
        std::string hex_error;
        auto parsed = modbus::parse_hex(tokens, hex_error);
        if (!parsed) {
            a.input_error(path + ":" + std::to_string(number) + ": not hex bytes: " + hex_error);
            ok = false;
            continue;
        }
        // "TIME [DIR] HEX...": a time (and direction) with no bytes is no chunk, a line cut or a logger
        // that wrote an empty read; it was counted as a packet of nothing.
        if (parsed->empty()) {
            a.input_error(path + ":" + std::to_string(number) +
                          ": a time and no bytes after it: " + modbus::quote_excerpt(line));
            ok = false;
            continue;
        }
        if (timed && t.count() == 0) t = modbus::Timestamp(1);  // zero means "untimed" to the analyzer
        a.serial(path, *parsed, t, dir.value_or(Direction::Unknown));
        bytes += parsed->size();
    }
    return ok;
}

bool read_raw(Analyzer& a, const Input& input, std::uint64_t& bytes) {
    const std::string& path = input.name;
    std::ifstream in(input.path, std::ios::binary);
    if (!in) {
        a.input_error(path + ": cannot open");
        return false;
    }
    std::vector<char> buf(1 << 16);
    std::uint64_t offset = 0;
    while (in) {
        in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
        const auto n = static_cast<std::size_t>(in.gcount());
        if (n) a.serial(path, {reinterpret_cast<const std::uint8_t*>(buf.data()), n}, modbus::Timestamp{0});
        offset += n;
        bytes += n;
        a.reached(offset);
    }
    return true;
}

bool read_log(Analyzer& a, const Input& input, InputFormat format, const SerialLogOptions& options,
              std::uint64_t& bytes) {
    const std::string& path = input.name;
    std::ifstream in(input.path, std::ios::binary);
    if (!in) {
        a.input_error(path + ": cannot open");
        return false;
    }
    Position position(a, in);
    const auto chunk = [&](const SerialChunk& c) {
        a.serial(path, c.bytes, c.received, c.direction);
        bytes += c.bytes.size();
        position.record();
    };
    const auto error = [&](const std::string& message) { a.input_error(message); };
    return format == InputFormat::Jpnevulator ? read_jpnevulator_log(in, path, options, chunk, error)
                                              : read_socat_log(in, path, options, chunk, error);
}

// A name that says "capture": .pcap, .pcapng, .cap, .ntar, .dmp (Wireshark's own), any case.
bool named_as_capture(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    for (auto& c : ext)
        c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return ext == ".pcap" || ext == ".pcapng" || ext == ".cap" || ext == ".ntar" || ext == ".dmp";
}

std::string first_bytes(const std::vector<char>& head) {
    if (head.empty()) return "none";
    return modbus::hex_bytes(
        {reinterpret_cast<const std::uint8_t*>(head.data()), std::min<std::size_t>(head.size(), 4)});
}

// Opens and is at its end; a file that cannot be opened is left to the reader, which names that.
bool holds_no_bytes(const Input& input) {
    std::ifstream in(input.path, std::ios::binary);
    return in && in.peek() == std::ifstream::traits_type::eof();
}

// Whether the head holds lines of hex bytes alone ("01 03 00 00 00 01 84 0A"), which the text format would
// read with its first byte for a time: "01" at 1 s, the line's other bytes a frame with a bad CRC, and the
// byte taken for a time counted nowhere. Every line that holds something is two-digit hex tokens (a comment
// after '#' aside), and something tells them from "TIME HEX...": a first token with a hex letter, which no
// time has, or a line whose bytes are a whole RTU frame (a valid CRC), which they are not without their
// first. The head's last line, cut by its end, is not judged.
bool hex_dump(std::span<const std::uint8_t> h) {
    const std::string_view text(reinterpret_cast<const char*>(h.data()), h.size());
    const auto is_pair = [](std::string_view t) {
        return t.size() == 2 && std::isxdigit(static_cast<unsigned char>(t[0])) &&
               std::isxdigit(static_cast<unsigned char>(t[1]));
    };
    bool told = false, any = false;
    for (std::size_t at = 0; at < text.size();) {
        std::size_t end = text.find('\n', at);
        if (end == std::string_view::npos) {
            if (h.size() >= 4096) break;  // a head cut by its size: its last line may be cut
            end = text.size();
        }
        std::string_view line = text.substr(at, end - at);
        at = end + 1;
        line = line.substr(0, line.find('#'));
        std::vector<std::uint8_t> bytes;
        for (std::size_t i = 0; i < line.size();) {
            if (line[i] == ' ' || line[i] == '\t' || line[i] == '\r') {
                ++i;
                continue;
            }
            const std::string_view token = line.substr(i, line.find_first_of(" \t\r", i) - i);
            if (!is_pair(token)) return false;
            if (bytes.empty() && !(std::isdigit(static_cast<unsigned char>(token[0])) &&
                                   std::isdigit(static_cast<unsigned char>(token[1]))))
                told = true;
            bytes.push_back(static_cast<std::uint8_t>(std::stoul(std::string(token), nullptr, 16)));
            i += token.size();
        }
        any |= !bytes.empty();
        if (bytes.size() >= 4 && modbus::rtu_crc_ok(bytes)) told = true;
    }
    return any && told;
}

}  // namespace

InputFormat detect_input_format(std::span<const std::uint8_t> h) {
    if (h.size() >= 4) {
        const std::uint32_t m = (std::uint32_t{h[0]} << 24) | (h[1] << 16) | (h[2] << 8) | h[3];
        if (m == 0xD4C3B2A1 || m == 0xA1B2C3D4 || m == 0x4D3CB2A1 || m == 0xA1B23C4D || m == 0x0A0D0D0A)
            return InputFormat::Pcap;
    }
    if (!h.empty() && h[0] == ':') return InputFormat::AsciiRaw;
    const std::string_view text(reinterpret_cast<const char*>(h.data()), h.size());
    if (looks_like_jpnevulator_log(text)) return InputFormat::Jpnevulator;
    if (looks_like_socat_log(text)) return InputFormat::Socat;
    if (hex_dump(h)) return InputFormat::Hex;
    // text: printable first line that starts with a number
    const auto text_line = [&](std::size_t i) {
        while (i < h.size() && (h[i] == ' ' || h[i] == '\t'))
            ++i;
        if (i >= h.size()) return false;
        // A sign before the time ("-5 > 11 03 ..."): still a time, one the reader refuses by name.
        const std::size_t digit = i + (h[i] == '-' || h[i] == '+' ? 1 : 0);
        if (digit >= h.size() || !(std::isdigit(h[digit]) || h[i] == '#')) return false;
        bool printable = true;
        bool words = h[i] == '#';  // a time and bytes: a line of one word is no chunk (an ASCII dump's tail)
        for (std::size_t k = i; k < h.size() && h[k] != '\n'; ++k) {
            printable &= h[k] == '\t' || h[k] == '\r' || (h[k] >= 0x20 && h[k] < 0x7F);
            words |= (h[k] == ' ' || h[k] == '\t') && k + 1 < h.size() && h[k + 1] > ' ';
        }
        return printable && words;
    };
    if (text_line(0)) return InputFormat::Text;
    // A first line the text format cannot read ("abc > 11 03 ...", a time of -5) made the whole log a raw
    // dump of its characters, "no Modbus frame", its good lines lost and no line named. Printable lines
    // throughout, a later one in the format: a text log with a bad line, which the reader names.
    const bool printable = std::all_of(h.begin(), h.end(), [](std::uint8_t c) {
        return c == '\t' || c == '\r' || c == '\n' || (c >= 0x20 && c < 0x7F);
    });
    const auto first_newline = std::find(h.begin(), h.end(), std::uint8_t{'\n'});
    if (printable && first_newline != h.end())
        for (std::size_t i = static_cast<std::size_t>(first_newline - h.begin()) + 1; i < h.size();) {
            if (text_line(i)) return InputFormat::Text;
            const auto next =
                std::find(h.begin() + static_cast<std::ptrdiff_t>(i), h.end(), std::uint8_t{'\n'});
            if (next == h.end()) break;
            i = static_cast<std::size_t>(next - h.begin()) + 1;
        }
    return InputFormat::RtuRaw;
}

namespace {

// An input opened and its format told, ready to be read.
struct Prepared {
    Input input;
    InputFormat asked;   // as given: Auto when the file's head told the format
    InputFormat format;  // what it is read as
    bool capture_read_as_serial = false;
};

// Opens an input and tells its format; nullopt (the error in the summary) when it cannot be read at all.
// `alone`: the only input, so that a capture through a pipe may be read as it comes (several captures are
// merged by time, which reads each ahead).
std::optional<Prepared> prepare(Analyzer& a, const std::string& name, InputFormat format, bool alone) {
    std::string error;
    auto input =
        open_input(name, error, alone && (format == InputFormat::Auto || format == InputFormat::Pcap));
    if (!input) {
        a.input_error(error);
        return std::nullopt;
    }
    Prepared p{std::move(*input), format, format};
    const std::string& path = p.input.name;
    if (p.input.stream) {
        p.format = InputFormat::Pcap;  // its magic number, read by open_input
    } else if (format != InputFormat::Pcap) {
        std::ifstream in(p.input.path, std::ios::binary);
        if (!in) {
            a.input_error(path + ": cannot open");
            return std::nullopt;
        }
        std::vector<char> head(4096);  // socat -d writes a few diagnostic lines before the first block
        in.read(head.data(), static_cast<std::streamsize>(head.size()));
        head.resize(static_cast<std::size_t>(in.gcount()));
        const InputFormat detected =
            detect_input_format({reinterpret_cast<const std::uint8_t*>(head.data()), head.size()});
        // A capture file read as serial bytes decodes to thousands of unparsed bytes and no error finding
        // (exit 0): say what the file is. It is still decoded as asked.
        p.capture_read_as_serial = format != InputFormat::Auto && detected == InputFormat::Pcap;
        if (p.capture_read_as_serial)
            a.input_error(path +
                          ": holds a pcap or pcapng capture (its magic number) but --format reads it as "
                          "serial bytes; leave --format out to decode the capture");
        if (format == InputFormat::Auto) p.format = detected;
        // Named as a capture and holding none: the wrong file, or one damaged from its first byte. Read as
        // serial bytes it "decoded" to unparsed bytes and exit 0; --format still reads it as asked.
        if (format == InputFormat::Auto && detected != InputFormat::Pcap && named_as_capture(path)) {
            a.input_error(path + ": named as a capture, but its first bytes (" + first_bytes(head) +
                          ") are no pcap or pcapng magic number: not a capture file (--format reads it "
                          "as another format)");
            return std::nullopt;
        }
    }
    // A file of no bytes decodes to nothing in every serial format; reporting that as a clean decode would
    // pass off a tap that recorded nothing (or the wrong file) as a quiet line. libpcap names an empty pcap
    // itself (a truncated file header).
    if (p.format != InputFormat::Pcap && holds_no_bytes(p.input)) {
        a.input_error(path + ": empty file, nothing to decode");
        return std::nullopt;
    }
    return p;
}

bool read_prepared(Analyzer& a, Prepared& p, const SerialLogOptions& options) {
    bool read = false;
    std::uint64_t bytes = 0;
    switch (p.format) {
        case InputFormat::Pcap: {
            if (!p.input.stream) return a.read_capture(p.input.path, p.input.name);
            std::string error;
            // While the writer is quiet, what was decoded so far is written out.
            auto capture = CaptureSource::open_stream(p.input.stream.release(), std::move(p.input.head),
                                                      p.input.name, error, [&a] { a.flush_output(); });
            if (!capture) {
                a.input_error(error);
                return false;
            }
            return a.read_capture(*capture);
        }
        case InputFormat::Text:
        case InputFormat::Hex:
            read = read_text(a, p.input, bytes, p.format == InputFormat::Text);
            break;
        case InputFormat::RtuRaw:
        case InputFormat::AsciiRaw:
            // Asked for by name, the format fixes the framing; found by its first byte, the line's bytes
            // tell it (a dump that starts inside a frame or with noise is not misread).
            if (p.asked != InputFormat::Auto && !a.serial_framing())
                a.set_serial_framing(p.format == InputFormat::AsciiRaw ? modbus::Framing::Ascii
                                                                       : modbus::Framing::Rtu);
            read = read_raw(a, p.input, bytes);
            break;
        case InputFormat::Jpnevulator:
        case InputFormat::Socat:
            read = read_log(a, p.input, p.format, options, bytes);
            break;
        case InputFormat::Auto:
            break;
    }
    // Read without an error and not one data byte in it (comments, a log's headers, a socat -d log of
    // diagnostics alone): nothing was decoded, as with an empty file, which is not a quiet line. A reader
    // that reported errors has said why already.
    if (read && bytes == 0) {
        a.input_error(p.input.name + ": no data bytes in it, nothing to decode");
        read = false;
    }
    return read && !p.capture_read_as_serial;
}

}  // namespace

bool read_input(Analyzer& a, const std::string& name, InputFormat format, const SerialLogOptions& options) {
    auto p = prepare(a, name, format, true);
    return p && read_prepared(a, *p, options);
}

bool read_inputs(Analyzer& a, const std::vector<std::string>& names, InputFormat format,
                 const SerialLogOptions& options, const std::function<void(const std::string&)>& done) {
    bool all_read = true;
    std::vector<Prepared> inputs;  // each holds its input open (a spooled pipe) until everything is read
    for (const auto& name : names) {
        auto p = prepare(a, name, format, names.size() == 1);
        if (p) {
            inputs.push_back(std::move(*p));
            continue;
        }
        all_read = false;
        if (done) done(name);
    }
    const auto is_capture = [](const Prepared& p) { return p.format == InputFormat::Pcap; };
    const auto captures = std::count_if(inputs.begin(), inputs.end(), is_capture);
    if (options.parts_of_one_line)
        if (const auto first = std::find_if_not(inputs.begin(), inputs.end(), is_capture);
            first != inputs.end())
            for (const auto& p : inputs)
                if (!is_capture(p)) a.serial_part_of(p.input.name, first->input.name);
    bool captures_read = false;
    for (auto& p : inputs) {
        if (!is_capture(p) || captures == 1) {
            all_read &= read_prepared(a, p, options);
            if (!is_capture(p) && inputs.size() > 1 && !options.parts_of_one_line) a.end_serial(p.input.name);
            if (done) done(p.input.name);
            continue;
        }
        if (captures_read) continue;  // read with the first
        captures_read = true;
        std::vector<CaptureFile> files;
        for (const auto& c : inputs)
            if (is_capture(c)) files.push_back({c.input.path, c.input.name});
        CaptureMerge merge(std::move(files));
        all_read &= a.read_capture(merge);
        if (done)
            for (const auto& c : inputs)
                if (is_capture(c)) done(c.input.name);
    }
    return all_read;
}

}  // namespace mbscope::analyzer
