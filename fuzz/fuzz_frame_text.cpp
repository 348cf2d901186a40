// Frames written as text (modbus/frame_text.hpp): `mbscope frame --file FILE` reads anyone's file, and the
// same hex spellings come from the command line. The input is the file. Every line that holds a frame is
// decoded (the direction drawn from its line number: unknown, request or response) and rendered as text and
// JSON. Properties: no crash and no exception escapes; line numbers rise and stay within the text; a line is
// a frame with at least one byte or an error; errors and rendered text hold no control character (a hostile
// file must not reach the terminal); the JSON holds the frame's length and bytes; the
// bytes written as a frames-file line read back as the same bytes.
#include <algorithm>
#include <string>
#include <string_view>

#include "fuzz/fuzz_support.hpp"
#include "modbus/describe.hpp"
#include "modbus/frame_text.hpp"

using namespace mbscope;
using modbus::Framing;

namespace {

constexpr const char* target = "fuzz_frame_text";

bool has_control_character(std::string_view text) {
    return std::any_of(text.begin(), text.end(), [](char c) {
        const auto u = static_cast<unsigned char>(c);
        return (u < 0x20 && c != '\n') || u == 0x7F;
    });
}

std::string where(const modbus::FrameLine& line) {
    return "line " + std::to_string(line.number) + ": ";
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    const std::size_t line_count = static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n')) + 1;
    std::size_t previous = 0;
    for (const auto& line : modbus::parse_frames_text(text)) {
        if (line.number <= previous || line.number > line_count)
            fuzz::fail(target, where(line) + "out of order or past the text's " + std::to_string(line_count));
        previous = line.number;
        if (!line.error.empty()) {
            if (has_control_character(line.error))
                fuzz::fail(target, where(line) + "a control character in the error: " + line.error);
            continue;
        }
        if (line.wire.empty()) fuzz::fail(target, where(line) + "neither bytes nor an error");

        static constexpr modbus::Direction directions[] = {
            modbus::Direction::Unknown, modbus::Direction::Request, modbus::Direction::Response};
        auto d = modbus::decode_frame(line.framing, line.wire, directions[line.number % 3]);
        d.source = "file:" + std::to_string(line.number) + " " + line.comment;
        const std::string shown = modbus::render_text(d);
        if (has_control_character(shown))
            fuzz::fail(target, where(line) + "a control character in the rendered text:\n" + shown);

        // The JSON as `--json` prints it, and the frame's bytes in it.
        const nlohmann::json json = modbus::render_json(d);
        (void)json.dump(2, ' ', false, nlohmann::json::error_handler_t::replace);
        if (json.value("length", std::size_t{0}) != line.wire.size())
            fuzz::fail(target, where(line) + "the JSON's length is not the frame's");
        if (line.framing != Framing::Ascii) {
            std::string error;
            const auto again =
                modbus::parse_hex(std::vector<std::string>{json.value("wire", std::string())}, error);
            if (!again || *again != line.wire)
                fuzz::fail(target, where(line) + "the JSON's wire is not the frame's bytes");
        }

        // The frame written as a frames-file line reads back as the same bytes (ASCII frames are written as
        // their hex bytes: the text may hold anything).
        const char* kind = line.framing == Framing::Tcp   ? "tcp "
                           : line.framing == Framing::Rtu ? "rtu "
                                                          : "ascii ";
        const std::string written = kind + modbus::hex_bytes(line.wire) + "\n";
        const auto reread = modbus::parse_frames_text(written);
        if (reread.size() != 1 || !reread.front().error.empty() || reread.front().wire != line.wire ||
            reread.front().framing != line.framing)
            fuzz::fail(target, where(line) + "written as '" + modbus::printable(written) +
                                   "' it reads back otherwise");
    }
    return 0;
}
