// mbscope frame: decode one ADU (or a file of them) field by field, or encode one.
#include <iostream>
#include <iterator>
#include <memory>

#include "cli/commands.hpp"
#include "cli/json_text.hpp"
#include "modbus/adu.hpp"
#include "modbus/describe.hpp"
#include "modbus/frame_text.hpp"
#include "modbus/storage/text_file.hpp"

namespace mbscope::cli {
namespace {

using namespace mbscope::modbus;

struct FrameOptions {
    bool rtu = false, ascii = false, tcp = false;
    bool encode = false;
    bool json = false;
    std::string direction = "auto";
    std::string file;
    int unit = 1;
    int transaction_id = 1;
    std::vector<std::string> args;
};

constexpr const char* encode_help =
    "Verbs for --encode (numbers in decimal or 0x hex; addresses are 0-based protocol addresses):\n"
    "  read-coils ADDR QTY | read-discrete ADDR QTY | read-holding ADDR QTY | read-input ADDR QTY\n"
    "  write-coil ADDR on|off | write-register ADDR VALUE\n"
    "  write-coils ADDR BIT... | write-registers ADDR VALUE...\n"
    "  read-write RADDR RQTY WADDR VALUE... | mask-write ADDR AND OR | read-fifo ADDR\n"
    "  diagnostics SUB [HEXDATA] | read-device-id CODE OBJECT | read-exception-status\n"
    "  comm-event-counter | comm-event-log | report-server-id\n"
    "  exception FC CODE | raw FC [HEXDATA]";

std::optional<long> number(const std::string& s) {
    try {
        std::size_t used = 0;
        long v = std::stol(s, &used, 0);
        if (used != s.size()) return std::nullopt;
        return v;
    } catch (...) {
        return std::nullopt;
    }
}

// Build a request PDU from a verb and its arguments; error says what is wrong.
std::optional<Pdu> build_pdu(const std::vector<std::string>& a, std::string& error) {
    if (a.empty()) {
        error = "--encode needs a verb";
        return std::nullopt;
    }
    const std::string& verb = a[0];
    std::vector<long> n;
    for (std::size_t i = 1; i < a.size(); ++i) {
        if (verb == "write-coil" && i == 2 && (a[i] == "on" || a[i] == "off")) {
            n.push_back(a[i] == "on" ? 1 : 0);
            continue;
        }
        if ((verb == "diagnostics" || verb == "raw") && i == 2) break;  // hex data handled below
        auto v = number(a[i]);
        if (!v || *v < 0 || *v > 0xFFFF) {
            error = "not a number from 0 to 65535: '" + a[i] + "'";
            return std::nullopt;
        }
        n.push_back(*v);
    }
    auto need = [&](std::size_t count, bool at_least = false) {
        if (at_least ? n.size() >= count : n.size() == count) return true;
        error = verb + " takes " + (at_least ? "at least " : "") + std::to_string(count) + " numbers";
        return false;
    };
    auto u16 = [](long v) { return static_cast<std::uint16_t>(v); };
    // One-byte fields (a function code, an exception code, a MEI object): a larger number is refused, not
    // cut to its low byte.
    auto one_byte_fields = [&](std::initializer_list<std::size_t> positions) {
        for (std::size_t i : positions)
            if (i < n.size() && n[i] > 0xFF) {
                error = verb + ": not a number from 0 to 255: '" + a[i + 1] + "'";
                return false;
            }
        return true;
    };
    auto words_from = [&](std::size_t from) {
        std::vector<std::uint16_t> w;
        for (std::size_t i = from; i < n.size(); ++i)
            w.push_back(u16(n[i]));
        return w;
    };
    auto hex_data = [&](std::size_t from) -> std::optional<std::vector<std::uint8_t>> {
        std::vector<std::string> tokens(a.begin() + static_cast<std::ptrdiff_t>(std::min(from, a.size())),
                                        a.end());
        return parse_hex(tokens, error);
    };
    const std::pair<const char*, FunctionCode> reads[] = {
        {"read-coils", FunctionCode::ReadCoils},
        {"read-discrete", FunctionCode::ReadDiscreteInputs},
        {"read-holding", FunctionCode::ReadHoldingRegisters},
        {"read-input", FunctionCode::ReadInputRegisters}};
    for (const auto& [name, fc] : reads)
        if (verb == name)
            return need(2) ? std::optional(make_read_request(fc, u16(n[0]), u16(n[1]))) : std::nullopt;
    if (verb == "write-coil")
        return need(2) ? std::optional(make_write_single_coil(u16(n[0]), n[1] != 0)) : std::nullopt;
    if (verb == "write-register")
        return need(2) ? std::optional(make_write_single_register(u16(n[0]), u16(n[1]))) : std::nullopt;
    if (verb == "write-coils") {
        if (!need(2, true)) return std::nullopt;
        std::vector<bool> bits;
        for (std::size_t i = 1; i < n.size(); ++i) {
            if (n[i] > 1) {
                error = "write-coils: a coil is 0 or 1, not '" + a[i + 1] + "'";
                return std::nullopt;
            }
            bits.push_back(n[i] != 0);
        }
        std::unique_ptr<bool[]> arr(new bool[bits.size()]);
        for (std::size_t i = 0; i < bits.size(); ++i)
            arr[i] = bits[i];
        return make_write_multiple_coils(u16(n[0]), {arr.get(), bits.size()});
    }
    if (verb == "write-registers") {
        if (!need(2, true)) return std::nullopt;
        auto w = words_from(1);
        return make_write_multiple_registers(u16(n[0]), w);
    }
    if (verb == "read-write") {
        if (!need(4, true)) return std::nullopt;
        auto w = words_from(3);
        return make_read_write_multiple(u16(n[0]), u16(n[1]), u16(n[2]), w);
    }
    if (verb == "mask-write")
        return need(3) ? std::optional(make_mask_write_register(u16(n[0]), u16(n[1]), u16(n[2])))
                       : std::nullopt;
    if (verb == "read-fifo") return need(1) ? std::optional(make_read_fifo_queue(u16(n[0]))) : std::nullopt;
    if (verb == "read-device-id")
        return need(2) && one_byte_fields({0, 1})
                   ? std::optional(make_read_device_id(static_cast<std::uint8_t>(n[0]),
                                                       static_cast<std::uint8_t>(n[1])))
                   : std::nullopt;
    if (verb == "diagnostics") {
        if (!need(1)) return std::nullopt;
        auto data = hex_data(2);
        if (!data) return std::nullopt;
        if (data->empty()) data = std::vector<std::uint8_t>{0x00, 0x00};
        return make_diagnostics(u16(n[0]), *data);
    }
    const std::pair<const char*, FunctionCode> no_data[] = {
        {"read-exception-status", FunctionCode::ReadExceptionStatus},
        {"comm-event-counter", FunctionCode::GetCommEventCounter},
        {"comm-event-log", FunctionCode::GetCommEventLog},
        {"report-server-id", FunctionCode::ReportServerId}};
    for (const auto& [name, fc] : no_data)
        if (verb == name) return need(0) ? std::optional(make_no_data_request(fc)) : std::nullopt;
    if (verb == "exception") {
        if (!need(2) || !one_byte_fields({0, 1})) return std::nullopt;
        return make_exception(static_cast<std::uint8_t>(n[0]), static_cast<std::uint8_t>(n[1]));
    }
    if (verb == "raw") {
        if (!need(1) || !one_byte_fields({0})) return std::nullopt;
        auto data = hex_data(2);
        if (!data) return std::nullopt;
        Pdu p;
        p.function_raw = static_cast<std::uint8_t>(n[0]);
        p.body = RawPdu{*data};
        return p;
    }
    error = "unknown verb '" + verb + "'";
    return std::nullopt;
}

Framing chosen_framing(const FrameOptions& o) {
    if (o.ascii) return Framing::Ascii;
    if (o.tcp) return Framing::Tcp;
    return Framing::Rtu;
}

Direction chosen_direction(const std::string& d) {
    if (d == "request") return Direction::Request;
    if (d == "response") return Direction::Response;
    return Direction::Unknown;
}

// Prints the frames decoded and returns the exit code they make. With `json`: one object for the frame given
// on the command line, an array for a file's frames (`as_array`) however many it holds. A file of one frame
// printed an object and a file of several an array, so a consumer had to handle both shapes.
int emit(const std::vector<DecodedFrame>& frames, bool json, bool as_array) {
    int rc = exit_ok;
    nlohmann::json all = nlohmann::json::array();
    for (const auto& d : frames) {
        if (json)
            all.push_back(render_json(d));
        else
            std::cout << render_text(d) << (frames.size() > 1 ? "\n" : "");
        if (!d.error.empty())
            rc = exit_failure;
        else if (d.broken() && rc == exit_ok)
            rc = exit_findings;
    }
    if (json) std::cout << json_text(as_array ? all : all.at(0)) << '\n';
    return rc;
}

int run_file(const FrameOptions& o) {
    std::string error;
    const auto text = modbus::storage::read_text_file(o.file, error);
    if (!text) {
        std::cerr << "mbscope frame: " << o.file << ": " << error << '\n';
        return exit_failure;
    }
    std::vector<DecodedFrame> frames;
    // A file that is not a frames file (a capture given by mistake) has an error on every line: the first
    // hundred are listed, the rest counted, as the analyzer does with its input errors.
    constexpr int listed_errors = 100;
    int errors = 0;
    for (auto& line : parse_frames_text(*text)) {
        if (!line.error.empty()) {
            if (++errors <= listed_errors)
                std::cerr << o.file << ":" << line.number << ": " << line.error << '\n';
            continue;
        }
        auto d = decode_frame(line.framing, std::move(line.wire), chosen_direction(o.direction));
        d.source =
            o.file + ":" + std::to_string(line.number) + (line.comment.empty() ? "" : " " + line.comment);
        frames.push_back(std::move(d));
    }
    if (errors > listed_errors)
        std::cerr << "mbscope frame: " << o.file << ": " << errors - listed_errors
                  << " more lines in error, not listed\n";
    if (frames.empty() && errors == 0) {
        std::cerr << "mbscope frame: " << o.file << " holds no frames\n";
        return exit_failure;
    }
    int rc = emit(frames, o.json, true);
    return errors ? exit_failure : rc;
}

int run_frame(const FrameOptions& o) {
    const int framings = int(o.rtu) + int(o.ascii) + int(o.tcp);
    if (framings > 1) {
        std::cerr << "mbscope frame: choose one of --rtu, --ascii, --tcp\n";
        return exit_failure;
    }
    if (!o.file.empty()) return run_file(o);
    if (framings == 0) {
        std::cerr << "mbscope frame: choose one of --rtu, --ascii, --tcp (or --file)\n";
        return exit_failure;
    }
    const Framing framing = chosen_framing(o);
    std::string error;
    if (o.encode) {
        if (o.unit < 0 || o.unit > 255 || o.transaction_id < 0 || o.transaction_id > 0xFFFF) {
            std::cerr << "mbscope frame: --unit is 0..255 and --tid 0..65535\n";
            return exit_failure;
        }
        auto pdu = build_pdu(o.args, error);
        if (!pdu) {
            std::cerr << "mbscope frame: " << error << "\n" << encode_help << '\n';
            return exit_failure;
        }
        auto bytes = encode_pdu(*pdu);
        // Past 253 bytes no framing can carry the PDU, and a byte count past 255 would wrap round: the frame
        // printed would not be the one asked for. Counts beyond the specification's that still fit (1,969
        // to 1,976 coils, quantities of a read) are encoded, and the decoding below names the limit they
        // break.
        if (bytes.size() > modbus::max_pdu_length) {
            std::cerr << "mbscope frame: " << o.args[0] << ": the PDU would be " << bytes.size()
                      << " bytes; a Modbus PDU holds at most " << modbus::max_pdu_length
                      << " (AP §4.1), so fewer values\n";
            return exit_failure;
        }
        auto wire = encode_adu(framing, static_cast<std::uint16_t>(o.transaction_id),
                               static_cast<std::uint8_t>(o.unit), std::move(bytes));
        return emit({decode_frame(framing, std::move(wire), pdu->direction)}, o.json, false);
    }
    auto wire = wire_from_tokens(framing, o.args, error);
    if (!wire) {
        std::cerr << "mbscope frame: " << error << '\n';
        return exit_failure;
    }
    if (wire->empty()) {
        std::cerr << "mbscope frame: no bytes given\n";
        return exit_failure;
    }
    return emit({decode_frame(framing, std::move(*wire), chosen_direction(o.direction))}, o.json, false);
}

}  // namespace

void register_frame(CLI::App& app, int& exit_code) {
    auto o = std::make_shared<FrameOptions>();
    auto* cmd = app.add_subcommand("frame", "Decode one Modbus ADU field by field, or encode one");
    cmd->footer(
        std::string("Examples:\n"
                    "  mbscope frame --rtu 11 03 00 60 00 03 07 45\n"
                    "  mbscope frame --ascii ':11100060000204000A01026C'\n"
                    "  mbscope frame --tcp 00 01 00 00 00 06 11 03 00 6B 00 03 --json\n"
                    "  mbscope frame --encode --rtu --unit 17 read-holding 96 3\n"
                    "  mbscope frame --file captures/manual-examples.txt\n\n") +
        encode_help +
        "\n\nExit codes: 0 decoded, no error (notes and warnings are shown: a function code that is"
        " not public, lowercase ASCII hex), 1 decoded but a rule is broken at error severity (checksum,"
        " limits), 2 could not decode.");
    cmd->add_flag("--rtu", o->rtu, "Modbus RTU: unit, PDU, CRC (low byte first)");
    cmd->add_flag("--ascii", o->ascii, "Modbus ASCII: ':' hex LRC CR LF (give the text or its bytes in hex)");
    auto* tcp = cmd->add_flag("--tcp", o->tcp, "Modbus/TCP: MBAP header and PDU");
    auto* encode = cmd->add_flag("--encode", o->encode,
                                 "Build a frame from a verb and its arguments instead of decoding");
    // An option that cannot act where it is given is refused rather than dropped: `--encode --rtu --tid 5`
    // printed a frame with no transaction id and exit 0, `--unit 5` on a frame decoded changed nothing.
    cmd->add_option("--unit", o->unit, "Unit id for --encode")->capture_default_str()->needs(encode);
    cmd->add_option("--tid", o->transaction_id, "Transaction id for --encode --tcp")
        ->capture_default_str()
        ->needs(encode)
        ->needs(tcp);
    cmd->add_option("--direction", o->direction, "request, response or auto (try both); not with --encode")
        ->check(CLI::IsMember({"auto", "request", "response"}))
        ->capture_default_str()
        ->excludes(encode);
    auto* file =
        cmd->add_option("--file", o->file, "Decode every line 'rtu|ascii|tcp HEX... [# comment]' of a file")
            ->excludes(encode);
    cmd->add_flag("--json", o->json,
                  "Machine-readable output: an object; with --file an array of them, one frame or many");
    cmd->add_option("bytes", o->args, "Hex bytes of the frame (or the verb and arguments with --encode)")
        ->excludes(file);
    cmd->callback([o, &exit_code] { exit_code = run_frame(*o); });
}

}  // namespace mbscope::cli
