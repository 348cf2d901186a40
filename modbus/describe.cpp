#include "modbus/describe.hpp"

#include <cstdio>

#include "modbus/addressing.hpp"
#include "modbus/json_writer.hpp"

namespace mbscope::modbus {

std::string hex_bytes(std::span<const std::uint8_t> bytes) {
    static constexpr char digits[] = "0123456789ABCDEF";
    std::string s;
    s.reserve(bytes.size() * 3);
    for (std::size_t i = 0; i < bytes.size(); ++i) {
        if (i) s.push_back(' ');
        s.push_back(digits[bytes[i] >> 4]);
        s.push_back(digits[bytes[i] & 0xF]);
    }
    return s;
}

std::string hex16(std::uint16_t v) {
    char buf[8];
    std::snprintf(buf, sizeof buf, "0x%04X", v);
    return buf;
}

std::string hex8(std::uint8_t v) {
    char buf[6];
    std::snprintf(buf, sizeof buf, "0x%02X", v);
    return buf;
}

namespace {

// What a field's value is, before it is made into a JSON value or written to a stream.
struct HexBytes {
    std::span<const std::uint8_t> bytes;
};
struct Words {
    const std::vector<std::uint16_t>& words;
};
struct Bits {
    std::span<const std::uint8_t> packed;
    std::size_t count;
};

std::string words_hex(const std::vector<std::uint16_t>& words) {
    std::string s;
    for (std::size_t i = 0; i < words.size(); ++i) {
        if (i) s += ' ';
        s += hex16(words[i]);
    }
    return s;
}

std::string reference_meaning(std::uint8_t fc, std::uint16_t address) {
    auto table = table_of_function(fc);
    std::string s = hex16(address);
    if (table) s += ", reference " + format_reference(to_reference(*table, ProtocolAddress{address}));
    return s;
}

// describe_pdu's output: every field with its JSON value and its meaning.
struct FieldList {
    std::vector<Field>& out;

    static nlohmann::json json_of(const HexBytes& v) { return hex_bytes(v.bytes); }
    static nlohmann::json json_of(const Words& v) {
        auto a = nlohmann::json::array();
        for (auto w : v.words)
            a.push_back(w);
        return a;
    }
    static nlohmann::json json_of(const Bits& v) {
        auto a = nlohmann::json::array();
        for (std::size_t i = 0; i < v.count; ++i)
            a.push_back(bit_at(v.packed, i) ? 1 : 0);
        return a;
    }
    static nlohmann::json json_of(const std::string& v) { return v; }
    template <class N>
    requires std::is_integral_v<N>
    static nlohmann::json json_of(N v) { return v; }

    // `meaning`: text, or a function that makes it (write_pdu_fields never asks for it).
    template <class V, class M>
    void add(std::string name, const V& value, M&& meaning) {
        std::string text;
        if constexpr (std::is_invocable_v<M>)
            text = meaning();
        else
            text = meaning;
        out.push_back(Field{std::move(name), json_of(value), std::move(text)});
    }
};

// write_pdu_fields' output: the values straight into a JSON stream, meanings never made.
struct FieldStream {
    JsonWriter& out;

    void write(const HexBytes& v) { out.hex_value(v.bytes); }
    void write(const Words& v) { out.value(std::span<const std::uint16_t>(v.words)); }
    void write(const Bits& v) {
        out.begin_array();
        for (std::size_t i = 0; i < v.count; ++i)
            out.value(bit_at(v.packed, i) ? 1 : 0);
        out.end_array();
    }
    void write(const std::string& v) { out.value(std::string_view(v)); }
    template <class N>
    requires std::is_integral_v<N>
    void write(N v) {
        if constexpr (std::is_signed_v<N>)
            out.value(static_cast<std::int64_t>(v));
        else
            out.value(static_cast<std::uint64_t>(v));
    }

    template <class V, class M>
    void add(std::string_view name, const V& value, M&&) {
        out.plain_key(name);  // field names are this file's literals and indexes
        write(value);
    }
};

template <class Out>
struct Describer {
    const Pdu& pdu;
    Out& out;
    void add(auto&& name, const auto& value) { out.add(std::forward<decltype(name)>(name), value, ""); }
    void add(auto&& name, const auto& value, auto&& meaning) {
        out.add(std::forward<decltype(name)>(name), value, meaning);
    }
    std::uint8_t fc() const { return pdu.function_code(); }
    auto reference(std::uint16_t address) const {
        return [fc = fc(), address] { return reference_meaning(fc, address); };
    }

    void operator()(const RawPdu& b) {
        add("data", HexBytes{b.data}, [&] { return std::to_string(b.data.size()) + " bytes"; });
    }
    void operator()(const ReadRequest& b) {
        add("starting_address", b.starting_address, reference(b.starting_address));
        add("quantity", b.quantity, fc() <= 2 ? "coils/inputs" : "registers");
    }
    void operator()(const WriteSingle& b) {
        add(fc() == 0x05 ? "output_address" : "register_address", b.address, reference(b.address));
        if (fc() == 0x05)
            add(
                "output_value", b.value,
                b.value == 0xFF00   ? "ON"
                : b.value == 0x0000 ? "OFF"
                                    : [&] { return hex16(b.value) + " (invalid: FF00 or 0000)"; }());
        else
            add("register_value", b.value, [&] {
                return hex16(b.value) + ", signed " + std::to_string(static_cast<std::int16_t>(b.value));
            });
    }
    void operator()(const NoData&) {}
    void operator()(const Diagnostics& b) {
        auto name = diagnostic_name(b.sub_function);
        add("sub_function", b.sub_function, name ? std::string(*name) : "reserved");
        add("data", HexBytes{b.data});
    }
    void operator()(const WriteMultipleCoilsRequest& b) {
        add("starting_address", b.starting_address, reference(b.starting_address));
        add("quantity", b.quantity, "coils");
        add("byte_count", b.byte_count);
        add("outputs_value", Bits{b.values, std::min<std::size_t>(b.quantity, b.values.size() * 8)},
            [&] { return hex_bytes(b.values); });
    }
    void operator()(const WriteMultipleRegistersRequest& b) {
        add("starting_address", b.starting_address, reference(b.starting_address));
        add("quantity", b.quantity, "registers");
        add("byte_count", b.byte_count);
        add("registers_value", Words{b.values}, [&] { return words_hex(b.values); });
    }
    void operator()(const FileRecordRequest& b) {
        add("byte_count", b.byte_count);
        for (std::size_t i = 0; i < b.sub_requests.size(); ++i) {
            const auto& s = b.sub_requests[i];
            const std::string p = "sub_request[" + std::to_string(i) + "].";
            add(p + "reference_type", s.reference_type);
            add(p + "file_number", s.file_number);
            add(p + "record_number", s.record_number);
            add(p + "record_length", s.record_length);
            if (!s.record_data.empty())
                add(p + "record_data", Words{s.record_data}, [&] { return words_hex(s.record_data); });
        }
    }
    void operator()(const MaskWriteRegister& b) {
        add("reference_address", b.reference_address, reference(b.reference_address));
        add("and_mask", b.and_mask, [&] { return hex16(b.and_mask); });
        add("or_mask", b.or_mask, [&] { return hex16(b.or_mask); });
    }
    void operator()(const ReadWriteMultipleRequest& b) {
        add("read_starting_address", b.read_starting_address, reference(b.read_starting_address));
        add("quantity_to_read", b.quantity_to_read);
        add("write_starting_address", b.write_starting_address, reference(b.write_starting_address));
        add("quantity_to_write", b.quantity_to_write);
        add("write_byte_count", b.write_byte_count);
        add("write_registers_value", Words{b.write_values}, [&] { return words_hex(b.write_values); });
    }
    void operator()(const ReadFifoQueueRequest& b) { add("fifo_pointer_address", b.fifo_pointer_address); }
    void operator()(const ReadDeviceIdRequest& b) {
        add("mei_type", mei_read_device_identification, "Read Device Identification");
        static constexpr const char* codes[] = {"?", "basic", "regular", "extended", "one specific object"};
        add("read_device_id_code", b.read_device_id_code,
            b.read_device_id_code <= 4 ? codes[b.read_device_id_code] : "invalid");
        add("object_id", b.object_id);
    }
    void operator()(const MeiTransport& b) {
        add("mei_type", b.mei_type,
            b.mei_type == mei_canopen_general_reference ? "CANopen General Reference" : "unknown");
        add("data", HexBytes{b.data});
    }
    void operator()(const ReadBitsResponse& b) {
        add("byte_count", b.byte_count);
        add("status", Bits{b.values, b.values.size() * 8},
            [&] { return hex_bytes(b.values) + " (LSB = first address)"; });
    }
    void operator()(const ReadRegistersResponse& b) {
        add("byte_count", b.byte_count);
        add("registers_value", Words{b.values}, [&] { return words_hex(b.values); });
    }
    void operator()(const ReadExceptionStatusResponse& b) {
        add("output_data", b.output_data, hex8(b.output_data));
    }
    void operator()(const CommEventCounterResponse& b) {
        add("status", b.status, b.status == 0xFFFF ? "busy" : "ready");
        add("event_count", b.event_count);
    }
    void operator()(const CommEventLogResponse& b) {
        add("byte_count", b.byte_count);
        add("status", b.status, b.status == 0xFFFF ? "busy" : "ready");
        add("event_count", b.event_count);
        add("message_count", b.message_count);
        add("events", HexBytes{b.events});
    }
    void operator()(const WriteMultipleResponse& b) {
        add("starting_address", b.starting_address, reference(b.starting_address));
        add("quantity", b.quantity);
    }
    void operator()(const ReportServerIdResponse& b) {
        add("byte_count", b.byte_count);
        add("data", HexBytes{b.data}, "server id, run indicator, device specific");
    }
    void operator()(const ReadFileRecordResponse& b) {
        add("byte_count", b.byte_count);
        for (std::size_t i = 0; i < b.sub_responses.size(); ++i) {
            const auto& s = b.sub_responses[i];
            const std::string p = "sub_response[" + std::to_string(i) + "].";
            add(p + "file_response_length", s.length);
            add(p + "reference_type", s.reference_type);
            add(p + "record_data", Words{s.record_data}, [&] { return words_hex(s.record_data); });
        }
    }
    void operator()(const ReadFifoQueueResponse& b) {
        add("byte_count", b.byte_count);
        add("fifo_count", b.fifo_count);
        add("fifo_value_register", Words{b.values}, [&] { return words_hex(b.values); });
    }
    void operator()(const ReadDeviceIdResponse& b) {
        add("mei_type", mei_read_device_identification, "Read Device Identification");
        add("read_device_id_code", b.read_device_id_code);
        add("conformity_level", b.conformity_level, hex8(b.conformity_level));
        add("more_follows", b.more_follows, b.more_follows ? "yes" : "no");
        add("next_object_id", b.next_object_id);
        add("number_of_objects", b.number_of_objects);
        static constexpr const char* names[] = {"VendorName",         "ProductCode", "MajorMinorRevision",
                                                "VendorUrl",          "ProductName", "ModelName",
                                                "UserApplicationName"};
        for (const auto& o : b.objects) {
            std::string text(o.value.begin(), o.value.end());
            add("object[" + std::to_string(o.id) + "]", text, o.id < 7 ? names[o.id] : "");
        }
    }
    void operator()(const ExceptionResponse& b) {
        auto name = exception_name(b.exception_code);
        add("exception_code", b.exception_code,
            name ? std::string(*name) : "not defined by the specification");
    }
};

}  // namespace

std::vector<Field> describe_pdu(const Pdu& pdu) {
    std::vector<Field> out;
    const auto name = function_name(pdu.function_code());
    std::string meaning = name ? std::string(*name)
                               : (is_user_defined_function(pdu.function_code()) ? "user-defined"
                                  : is_reserved_function(pdu.function_code())   ? "reserved"
                                                                                : "unassigned");
    if ((pdu.function_raw & exception_bit) != 0) meaning += " (exception)";
    out.push_back(Field{"function_code", pdu.function_raw, meaning});
    FieldList list{out};
    std::visit(Describer<FieldList>{pdu, list}, pdu.body);
    return out;
}

void write_pdu_fields(const Pdu& pdu, JsonWriter& out) {
    FieldStream stream{out};
    out.begin_object();
    std::visit(Describer<FieldStream>{pdu, stream}, pdu.body);
    out.end_object();
}

std::vector<Field> describe_framing(const Frame& f) {
    std::vector<Field> out;
    switch (f.framing) {
        case Framing::Tcp:
            out.push_back({"transaction_id", f.transaction_id(), hex16(f.transaction_id())});
            out.push_back({"protocol_id", f.protocol_id(), f.protocol_id() == 0 ? "Modbus" : "not Modbus"});
            out.push_back({"length", f.length_field(), "unit id + PDU bytes"});
            out.push_back({"unit_id", f.unit_id(), ""});
            break;
        case Framing::Rtu:
        case Framing::Ascii: {
            const auto unit = f.unit_id();
            out.push_back({"unit_id", unit, unit == 0 ? "broadcast" : unit >= 248 ? "reserved" : ""});
            break;
        }
    }
    if (f.framing == Framing::Rtu) {
        const std::string received = hex16(f.checksum_received());
        out.push_back({"crc", received,
                       f.checksum_ok ? "ok (sent low byte first)"
                                     : "mismatch: computed " + hex16(f.checksum_computed())});
    } else if (f.framing == Framing::Ascii) {
        out.push_back({"lrc", hex8(static_cast<std::uint8_t>(f.checksum_received())),
                       f.checksum_ok
                           ? "ok"
                           : "mismatch: computed " + hex8(static_cast<std::uint8_t>(f.checksum_computed()))});
    }
    return out;
}

}  // namespace mbscope::modbus
