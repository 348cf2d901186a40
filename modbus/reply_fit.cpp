#include "modbus/reply_fit.hpp"

#include <algorithm>

#include "modbus/describe.hpp"

namespace mbscope::modbus {

namespace {

using Kind = ReplyMisfit::Kind;

std::string registers(std::uint16_t n) {
    return std::to_string(n) + (n == 1 ? " register" : " registers");
}

// AP §6.8.1: the sub-functions whose normal response echoes the request's data.
bool echoing_sub_function(std::uint16_t sub) {
    return sub == 0x00 || sub == 0x01 || sub == 0x03 || sub == 0x0A || sub == 0x14;
}

// The data bytes a read's reply carries (AP §6.1-6.4, §6.17): a bit per coil or input, two per register.
std::optional<std::size_t> read_data_bytes(const Pdu& request) {
    if (const auto* read = std::get_if<ReadRequest>(&request.body))
        return request.function_code() <= 2 ? (read->quantity + 7u) / 8u : 2u * read->quantity;
    if (const auto* rw = std::get_if<ReadWriteMultipleRequest>(&request.body))
        return 2u * rw->quantity_to_read;
    return std::nullopt;
}

// What the reply to a multiple write echoes: its starting address and quantity (AP §6.11, §6.12).
std::optional<WriteMultipleResponse> multiple_write_echo(const Pdu& request) {
    if (const auto* c = std::get_if<WriteMultipleCoilsRequest>(&request.body))
        return WriteMultipleResponse{c->starting_address, c->quantity};
    if (const auto* w = std::get_if<WriteMultipleRegistersRequest>(&request.body))
        return WriteMultipleResponse{w->starting_address, w->quantity};
    return std::nullopt;
}

// The fields in which an echo differs from what it echoes, in words ("its value is 927, not 926"; several
// joined by "; "); nothing when the response's body is of another shape.
std::string echo_differences(const Pdu& request, const Pdu& response) {
    std::string out;
    const auto field = [&](const char* name, std::string got, std::string due) {
        if (got == due) return;
        out += (out.empty() ? "its " : "; its ") + std::string(name) + " is " + got + ", not " + due;
    };
    const auto number = [](std::uint16_t v) { return std::to_string(v); };
    if (const auto* q = std::get_if<WriteSingle>(&request.body)) {
        const auto* a = std::get_if<WriteSingle>(&response.body);
        if (!a) return out;
        field("address", number(a->address), number(q->address));
        // A coil's value is one of two words, 0xFF00 and 0x0000 (AP §6.5), said as such.
        const bool coil = request.function_code() == 5;
        field("value", coil ? hex16(a->value) : number(a->value), coil ? hex16(q->value) : number(q->value));
    } else if (const auto* q = std::get_if<MaskWriteRegister>(&request.body)) {
        const auto* a = std::get_if<MaskWriteRegister>(&response.body);
        if (!a) return out;
        field("reference address", number(a->reference_address), number(q->reference_address));
        field("AND mask", hex16(a->and_mask), hex16(q->and_mask));
        field("OR mask", hex16(a->or_mask), hex16(q->or_mask));
    } else if (const auto* q = std::get_if<Diagnostics>(&request.body)) {
        const auto* a = std::get_if<Diagnostics>(&response.body);
        if (!a) return out;
        // Another sub-function's data is that one's answer, not a wrong echo: the sub-function alone is said.
        field("sub-function", number(a->sub_function), number(q->sub_function));
        if (!out.empty()) return out;
        const auto data = [](const std::vector<std::uint8_t>& d) {
            if (d.empty()) return std::string("empty");
            if (d.size() <= 16) return hex_bytes(d);
            // A message, not a dump: the frames are in the record.
            return hex_bytes(std::span(d).first(16)) + " ... (" + std::to_string(d.size()) + " bytes)";
        };
        const auto [got, due] = std::mismatch(a->data.begin(), a->data.end(), q->data.begin(), q->data.end());
        const auto at = static_cast<std::size_t>(got - a->data.begin());
        if (got == a->data.end() && due == q->data.end()) return out;
        if (at < 16 || a->data.size() != q->data.size())  // the shortened texts differ
            field("data", data(a->data), data(q->data));
        else
            out = "its data's byte " + std::to_string(at + 1) + " is " + hex8(*got) + ", not " + hex8(*due);
    } else if (const auto echo = multiple_write_echo(request)) {
        const auto* a = std::get_if<WriteMultipleResponse>(&response.body);
        if (!a) return out;
        field("starting address", number(a->starting_address), number(echo->starting_address));
        field("quantity", number(a->quantity), number(echo->quantity));
    }
    return out;
}

}  // namespace

std::optional<ReplyMisfit> reply_misfit(const Pdu& request, const Pdu& response) {
    if (response.is_exception() || response.function_code() != request.function_code()) return std::nullopt;
    const std::uint8_t fc = request.function_code();
    const auto echo = [&](const char* source) -> std::optional<ReplyMisfit> {
        if (request.body == response.body) return std::nullopt;
        return ReplyMisfit{Kind::Echo, "an echo of the request",           source, 0,
                           0,          echo_differences(request, response)};
    };
    if (const auto* read = std::get_if<ReadRequest>(&request.body)) {
        if (fc <= 2) {
            const std::size_t bytes = *read_data_bytes(request);
            const auto* bits = std::get_if<ReadBitsResponse>(&response.body);
            if (!bits || bits->values.size() != bytes)
                return ReplyMisfit{Kind::DataSize, std::to_string(bytes) + " data bytes", "AP §6.1", bytes,
                                   bits ? bits->values.size() : 0};
            if (padding_bits_set(bits->values, read->quantity))
                return ReplyMisfit{Kind::Padding, "the bits of the last byte past the quantity asked zero",
                                   "AP §6.1"};
            return std::nullopt;
        }
        const auto* regs = std::get_if<ReadRegistersResponse>(&response.body);
        if (!regs || regs->values.size() != read->quantity)
            return ReplyMisfit{Kind::DataSize, registers(read->quantity), "AP §6.3", 2u * read->quantity,
                               regs ? 2 * regs->values.size() : 0};
        return std::nullopt;
    }
    if (const auto* rw = std::get_if<ReadWriteMultipleRequest>(&request.body)) {
        const auto* regs = std::get_if<ReadRegistersResponse>(&response.body);
        if (!regs || regs->values.size() != rw->quantity_to_read)
            return ReplyMisfit{Kind::DataSize, registers(rw->quantity_to_read), "AP §6.17",
                               2u * rw->quantity_to_read, regs ? 2 * regs->values.size() : 0};
        return std::nullopt;
    }
    switch (fc) {
        case 5:
            return echo("AP §6.5");
        case 6:
            return echo("AP §6.6");
        case 22:
            return echo("AP §6.16");
        case 8: {
            const auto* q = std::get_if<Diagnostics>(&request.body);
            const auto* a = std::get_if<Diagnostics>(&response.body);
            if (!q) return std::nullopt;
            if (!a || a->sub_function != q->sub_function)
                return ReplyMisfit{Kind::Echo, "an echo of the request's sub-function",
                                   "AP §6.8",  0,
                                   0,          a ? echo_differences(request, response) : std::string()};
            return echoing_sub_function(q->sub_function) ? echo("AP §6.8.1") : std::nullopt;
        }
        case 15:
        case 16: {
            const auto* a = std::get_if<WriteMultipleResponse>(&response.body);
            const auto echo_due = multiple_write_echo(request);
            if (!echo_due) return std::nullopt;
            if (!a || *a != *echo_due)
                return ReplyMisfit{
                    Kind::Echo, "an echo of the request's starting address and quantity", "AP §6.11-6.12", 0,
                    0,          a ? echo_differences(request, response) : std::string()};
            return std::nullopt;
        }
        default:
            return std::nullopt;
    }
}

bool reply_claims_to_answer(const Pdu& request, std::span<const std::uint8_t> reply_pdu) noexcept {
    const auto word = [&](std::size_t at) {
        return static_cast<std::uint16_t>(reply_pdu[at] << 8 | reply_pdu[at + 1]);
    };
    if (const auto bytes = read_data_bytes(request))
        return reply_pdu.size() >= 2 && (reply_pdu[1] == *bytes || reply_pdu[1] == reply_pdu.size() - 2);
    const auto echo_due = multiple_write_echo(request);
    if (!echo_due) return true;
    return reply_pdu.size() == 5 ||
           (reply_pdu.size() > 5 && word(1) == echo_due->starting_address && word(3) == echo_due->quantity);
}

}  // namespace mbscope::modbus
