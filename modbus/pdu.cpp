#include "modbus/pdu.hpp"

#include "modbus/byte_reader.hpp"

namespace mbscope::modbus {

std::string_view to_string(Direction d) noexcept {
    switch (d) {
        case Direction::Request:
            return "request";
        case Direction::Response:
            return "response";
        case Direction::Unknown:
            return "unknown";
    }
    return "unknown";
}

namespace {

using Code = FunctionCode;

constexpr bool is(std::uint8_t fc, Code c) {
    return fc == static_cast<std::uint8_t>(c);
}

DecodeError truncated(const ByteReader& r) {
    return make_error(ErrorCode::Truncated, r.offset());
}

// Finish: a fixed-layout PDU must have consumed every byte.
Result<Pdu> finish(Pdu pdu, const ByteReader& r) {
    if (!r.empty()) return make_error(ErrorCode::TrailingBytes, r.offset());
    return pdu;
}

std::vector<std::uint16_t> read_words(std::span<const std::uint8_t> bytes) {
    std::vector<std::uint16_t> words(bytes.size() / 2);
    for (std::size_t i = 0; i < words.size(); ++i)
        words[i] = static_cast<std::uint16_t>((bytes[2 * i] << 8) | bytes[2 * i + 1]);
    return words;
}

void check_quantity(Pdu& pdu, std::uint16_t quantity, std::uint16_t max) {
    if (quantity == 0 || quantity > max) pdu.violations.add(FindingCode::PduQuantityOutOfRange);
}

void check_span(Pdu& pdu, std::uint16_t start, std::uint16_t quantity) {
    if (static_cast<std::uint32_t>(start) + quantity > 0x10000u)
        pdu.violations.add(FindingCode::PduAddressOverflow);
}

void check_padding(Pdu& pdu, std::span<const std::uint8_t> packed, std::uint16_t quantity) {
    if (padding_bits_set(packed, quantity)) pdu.violations.add(FindingCode::PduPaddingBitsSet);
}

Result<Pdu> decode_file_sub_requests(Pdu pdu, ByteReader& r, bool with_data) {
    auto bc = r.u8();
    if (!bc) return truncated(r);
    FileRecordRequest body{*bc, {}};
    if (*bc < min_file_request_bytes || *bc > max_file_request_bytes || *bc != r.remaining())
        pdu.violations.add(FindingCode::PduByteCountMismatch);
    while (!r.empty()) {
        FileSubRequest sub;
        auto type = r.u8();
        auto file = r.u16();
        auto record = r.u16();
        auto length = r.u16();
        if (!type || !file || !record || !length) return truncated(r);
        sub.reference_type = *type;
        sub.file_number = *file;
        sub.record_number = *record;
        sub.record_length = *length;
        if (*type != file_reference_type || *record > max_file_record_number)
            pdu.violations.add(FindingCode::PduFileRecordInvalid);
        if (with_data) {
            auto data = r.take(static_cast<std::size_t>(*length) * 2);
            if (!data) return truncated(r);
            sub.record_data = read_words(*data);
        }
        body.sub_requests.push_back(std::move(sub));
    }
    pdu.body = std::move(body);
    return pdu;
}

Result<Pdu> decode_request_body(Pdu pdu, ByteReader& r) {
    const std::uint8_t fc = pdu.function_code();
    if (is(fc, Code::ReadCoils) || is(fc, Code::ReadDiscreteInputs) || is(fc, Code::ReadHoldingRegisters) ||
        is(fc, Code::ReadInputRegisters)) {
        auto start = r.u16();
        auto qty = r.u16();
        if (!start || !qty) return truncated(r);
        const bool bits = fc <= 0x02;
        check_quantity(pdu, *qty, bits ? max_read_bits : max_read_registers);
        check_span(pdu, *start, *qty);
        pdu.body = ReadRequest{*start, *qty};
        return finish(std::move(pdu), r);
    }
    if (is(fc, Code::WriteSingleCoil) || is(fc, Code::WriteSingleRegister)) {
        auto address = r.u16();
        auto value = r.u16();
        if (!address || !value) return truncated(r);
        if (is(fc, Code::WriteSingleCoil) && *value != 0xFF00 && *value != 0x0000)
            pdu.violations.add(FindingCode::PduCoilValueInvalid);
        pdu.body = WriteSingle{*address, *value};
        return finish(std::move(pdu), r);
    }
    if (is(fc, Code::ReadExceptionStatus) || is(fc, Code::GetCommEventCounter) ||
        is(fc, Code::GetCommEventLog) || is(fc, Code::ReportServerId)) {
        pdu.body = NoData{};
        return finish(std::move(pdu), r);
    }
    if (is(fc, Code::Diagnostics)) {
        auto sub = r.u16();
        if (!sub) return truncated(r);
        auto data = r.rest();
        if (!diagnostic_name(*sub)) pdu.violations.add(FindingCode::PduReservedSubFunction);
        // AP §6.8.1: every sub-function but 00 (echo of any data) carries one 16-bit data field; 15 hex
        // (Modbus Plus statistics) answers with more.
        if (*sub != 0x00 && *sub != 0x15 && data.size() != 2)
            pdu.violations.add(FindingCode::PduDiagnosticDataLength);
        pdu.body = Diagnostics{*sub, {data.begin(), data.end()}};
        return pdu;
    }
    if (is(fc, Code::WriteMultipleCoils)) {
        auto start = r.u16();
        auto qty = r.u16();
        auto bc = r.u8();
        if (!start || !qty || !bc) return truncated(r);
        auto values = r.rest();
        check_quantity(pdu, *qty, max_write_bits);
        check_span(pdu, *start, *qty);
        if (*bc != values.size() || *bc != (*qty + 7u) / 8u)
            pdu.violations.add(FindingCode::PduByteCountMismatch);
        check_padding(pdu, values, *qty);
        pdu.body = WriteMultipleCoilsRequest{*start, *qty, *bc, {values.begin(), values.end()}};
        return pdu;
    }
    if (is(fc, Code::WriteMultipleRegisters)) {
        auto start = r.u16();
        auto qty = r.u16();
        auto bc = r.u8();
        if (!start || !qty || !bc) return truncated(r);
        auto values = r.rest();
        check_quantity(pdu, *qty, max_write_registers);
        check_span(pdu, *start, *qty);
        if (*bc != values.size() || *bc != 2u * *qty || values.size() % 2 != 0)
            pdu.violations.add(FindingCode::PduByteCountMismatch);
        pdu.body = WriteMultipleRegistersRequest{*start, *qty, *bc, read_words(values)};
        return pdu;
    }
    if (is(fc, Code::ReadFileRecord)) return decode_file_sub_requests(std::move(pdu), r, false);
    if (is(fc, Code::WriteFileRecord)) return decode_file_sub_requests(std::move(pdu), r, true);
    if (is(fc, Code::MaskWriteRegister)) {
        auto address = r.u16();
        auto and_mask = r.u16();
        auto or_mask = r.u16();
        if (!address || !and_mask || !or_mask) return truncated(r);
        pdu.body = MaskWriteRegister{*address, *and_mask, *or_mask};
        return finish(std::move(pdu), r);
    }
    if (is(fc, Code::ReadWriteMultipleRegisters)) {
        auto read_start = r.u16();
        auto read_qty = r.u16();
        auto write_start = r.u16();
        auto write_qty = r.u16();
        auto bc = r.u8();
        if (!read_start || !read_qty || !write_start || !write_qty || !bc) return truncated(r);
        auto values = r.rest();
        if (*read_qty == 0 || *read_qty > max_rw_read_registers || *write_qty == 0 ||
            *write_qty > max_rw_write_registers)
            pdu.violations.add(FindingCode::PduQuantityOutOfRange);
        check_span(pdu, *read_start, *read_qty);
        check_span(pdu, *write_start, *write_qty);
        if (*bc != values.size() || *bc != 2u * *write_qty || values.size() % 2 != 0)
            pdu.violations.add(FindingCode::PduByteCountMismatch);
        pdu.body = ReadWriteMultipleRequest{*read_start, *read_qty, *write_start,
                                            *write_qty,  *bc,       read_words(values)};
        return pdu;
    }
    if (is(fc, Code::ReadFifoQueue)) {
        auto pointer = r.u16();
        if (!pointer) return truncated(r);
        pdu.body = ReadFifoQueueRequest{*pointer};
        return finish(std::move(pdu), r);
    }
    if (is(fc, Code::EncapsulatedInterface)) {
        auto mei = r.u8();
        if (!mei) return truncated(r);
        if (*mei == mei_read_device_identification) {
            auto code = r.u8();
            auto object = r.u8();
            if (!code || !object) return truncated(r);
            if (*code < 1 || *code > 4) pdu.violations.add(FindingCode::PduDeviceIdCodeInvalid);
            pdu.body = ReadDeviceIdRequest{*code, *object};
            return finish(std::move(pdu), r);
        }
        if (*mei != mei_canopen_general_reference) pdu.violations.add(FindingCode::PduMeiTypeUnknown);
        auto data = r.rest();
        pdu.body = MeiTransport{*mei, {data.begin(), data.end()}};
        return pdu;
    }
    pdu.violations.add(FindingCode::PduUnknownFunction);
    auto data = r.rest();
    pdu.body = RawPdu{{data.begin(), data.end()}};
    return pdu;
}

// Responses whose data is "byte count + that many bytes".
std::span<const std::uint8_t> counted_bytes(Pdu& pdu, ByteReader& r, std::uint8_t bc) {
    auto values = r.rest();
    if (bc != values.size()) pdu.violations.add(FindingCode::PduByteCountMismatch);
    return values;
}

Result<Pdu> decode_device_id_response(Pdu pdu, ByteReader& r) {
    auto code = r.u8();
    auto conformity = r.u8();
    auto more = r.u8();
    auto next = r.u8();
    auto count = r.u8();
    if (!code || !conformity || !more || !next || !count) return truncated(r);
    ReadDeviceIdResponse body{*code, *conformity, *more, *next, *count, {}};
    if (*code < 1 || *code > 4) pdu.violations.add(FindingCode::PduDeviceIdCodeInvalid);
    for (unsigned i = 0; i < *count; ++i) {
        auto id = r.u8();
        auto len = r.u8();
        if (!id || !len) return truncated(r);
        auto value = r.take(*len);
        if (!value) return truncated(r);
        body.objects.push_back(DeviceIdObject{*id, {value->begin(), value->end()}});
    }
    pdu.body = std::move(body);
    return finish(std::move(pdu), r);
}

Result<Pdu> decode_response_body(Pdu pdu, ByteReader& r) {
    const std::uint8_t fc = pdu.function_code();
    if ((pdu.function_raw & exception_bit) != 0) {
        auto code = r.u8();
        if (!code) return truncated(r);
        if (!exception_name(*code)) pdu.violations.add(FindingCode::PduUnknownExceptionCode);
        if (!is_public_function(fc)) pdu.violations.add(FindingCode::PduUnknownFunction);
        pdu.body = ExceptionResponse{*code};
        return finish(std::move(pdu), r);
    }
    if (is(fc, Code::ReadCoils) || is(fc, Code::ReadDiscreteInputs)) {
        auto bc = r.u8();
        if (!bc) return truncated(r);
        auto values = counted_bytes(pdu, r, *bc);
        pdu.body = ReadBitsResponse{*bc, {values.begin(), values.end()}};
        return pdu;
    }
    if (is(fc, Code::ReadHoldingRegisters) || is(fc, Code::ReadInputRegisters) ||
        is(fc, Code::ReadWriteMultipleRegisters)) {
        auto bc = r.u8();
        if (!bc) return truncated(r);
        auto values = counted_bytes(pdu, r, *bc);
        if (values.size() % 2 != 0 || *bc % 2 != 0) pdu.violations.add(FindingCode::PduByteCountMismatch);
        const std::size_t max_registers =
            is(fc, Code::ReadWriteMultipleRegisters) ? max_rw_read_registers : max_read_registers;
        // The quantity the reply states is its byte count's: fewer bytes present is the byte count's
        // mismatch (a reply cut short), not a quantity of 0 as well.
        if (*bc / 2u > max_registers || *bc == 0) pdu.violations.add(FindingCode::PduQuantityOutOfRange);
        pdu.body = ReadRegistersResponse{*bc, read_words(values)};
        return pdu;
    }
    if (is(fc, Code::WriteSingleCoil) || is(fc, Code::WriteSingleRegister)) {
        auto address = r.u16();
        auto value = r.u16();
        if (!address || !value) return truncated(r);
        if (is(fc, Code::WriteSingleCoil) && *value != 0xFF00 && *value != 0x0000)
            pdu.violations.add(FindingCode::PduCoilValueInvalid);
        pdu.body = WriteSingle{*address, *value};
        return finish(std::move(pdu), r);
    }
    if (is(fc, Code::ReadExceptionStatus)) {
        auto data = r.u8();
        if (!data) return truncated(r);
        pdu.body = ReadExceptionStatusResponse{*data};
        return finish(std::move(pdu), r);
    }
    if (is(fc, Code::Diagnostics)) {
        auto sub = r.u16();
        if (!sub) return truncated(r);
        auto data = r.rest();
        if (!diagnostic_name(*sub)) pdu.violations.add(FindingCode::PduReservedSubFunction);
        // AP §6.8.1: every sub-function but 00 (echo of any data) carries one 16-bit data field; 15 hex
        // (Modbus Plus statistics) answers with more.
        if (*sub != 0x00 && *sub != 0x15 && data.size() != 2)
            pdu.violations.add(FindingCode::PduDiagnosticDataLength);
        pdu.body = Diagnostics{*sub, {data.begin(), data.end()}};
        return pdu;
    }
    if (is(fc, Code::GetCommEventCounter)) {
        auto status = r.u16();
        auto count = r.u16();
        if (!status || !count) return truncated(r);
        pdu.body = CommEventCounterResponse{*status, *count};
        return finish(std::move(pdu), r);
    }
    if (is(fc, Code::GetCommEventLog)) {
        auto bc = r.u8();
        auto status = r.u16();
        auto events = r.u16();
        auto messages = r.u16();
        if (!bc || !status || !events || !messages) return truncated(r);
        auto rest = r.rest();
        if (*bc != rest.size() + 6) pdu.violations.add(FindingCode::PduByteCountMismatch);
        pdu.body = CommEventLogResponse{*bc, *status, *events, *messages, {rest.begin(), rest.end()}};
        return pdu;
    }
    if (is(fc, Code::WriteMultipleCoils) || is(fc, Code::WriteMultipleRegisters)) {
        auto start = r.u16();
        auto qty = r.u16();
        if (!start || !qty) return truncated(r);
        check_quantity(pdu, *qty, is(fc, Code::WriteMultipleCoils) ? max_write_bits : max_write_registers);
        pdu.body = WriteMultipleResponse{*start, *qty};
        return finish(std::move(pdu), r);
    }
    if (is(fc, Code::ReportServerId)) {
        auto bc = r.u8();
        if (!bc) return truncated(r);
        auto data = counted_bytes(pdu, r, *bc);
        pdu.body = ReportServerIdResponse{*bc, {data.begin(), data.end()}};
        return pdu;
    }
    if (is(fc, Code::ReadFileRecord)) {
        auto bc = r.u8();
        if (!bc) return truncated(r);
        // A request reads at least one record (its byte count is 0x07 or more), so a reply with no
        // sub-response answers none. AP §6.14 gives the reply's byte count the request's range, 0x07..0xF5,
        // which one record of one register (4 bytes) falls below and its own example's sub-response length
        // 0x05 contradicts: only the empty reply is refused.
        if (*bc != r.remaining() || *bc == 0) pdu.violations.add(FindingCode::PduByteCountMismatch);
        ReadFileRecordResponse body{*bc, {}};
        while (!r.empty()) {
            auto len = r.u8();
            auto type = r.u8();
            if (!len || !type) return truncated(r);
            if (*len < 1) return make_error(ErrorCode::ByteCountMismatch, r.offset() - 2);
            auto data = r.take(*len - 1u);
            if (!data) return truncated(r);
            if (*type != file_reference_type || data->size() % 2 != 0)
                pdu.violations.add(FindingCode::PduFileRecordInvalid);
            body.sub_responses.push_back(FileSubResponse{*len, *type, read_words(*data)});
        }
        pdu.body = std::move(body);
        return pdu;
    }
    if (is(fc, Code::WriteFileRecord)) return decode_file_sub_requests(std::move(pdu), r, true);
    if (is(fc, Code::MaskWriteRegister)) {
        auto address = r.u16();
        auto and_mask = r.u16();
        auto or_mask = r.u16();
        if (!address || !and_mask || !or_mask) return truncated(r);
        pdu.body = MaskWriteRegister{*address, *and_mask, *or_mask};
        return finish(std::move(pdu), r);
    }
    if (is(fc, Code::ReadFifoQueue)) {
        auto bc = r.u16();
        auto count = r.u16();
        if (!bc || !count) return truncated(r);
        auto values = r.rest();
        if (*bc != values.size() + 2 || values.size() != 2u * *count || values.size() % 2 != 0)
            pdu.violations.add(FindingCode::PduByteCountMismatch);
        if (*count > max_fifo_count) pdu.violations.add(FindingCode::PduFifoCountTooLarge);
        pdu.body = ReadFifoQueueResponse{*bc, *count, read_words(values)};
        return pdu;
    }
    if (is(fc, Code::EncapsulatedInterface)) {
        auto mei = r.u8();
        if (!mei) return truncated(r);
        if (*mei == mei_read_device_identification) return decode_device_id_response(std::move(pdu), r);
        if (*mei != mei_canopen_general_reference) pdu.violations.add(FindingCode::PduMeiTypeUnknown);
        auto data = r.rest();
        pdu.body = MeiTransport{*mei, {data.begin(), data.end()}};
        return pdu;
    }
    pdu.violations.add(FindingCode::PduUnknownFunction);
    auto data = r.rest();
    pdu.body = RawPdu{{data.begin(), data.end()}};
    return pdu;
}

}  // namespace

Result<Pdu> decode_request(std::span<const std::uint8_t> bytes) noexcept {
    ByteReader r(bytes);
    auto fc = r.u8();
    if (!fc) return make_error(ErrorCode::EmptyPdu, 0);
    Pdu pdu;
    pdu.function_raw = *fc;
    pdu.direction = Direction::Request;
    if ((pdu.function_raw & exception_bit) != 0) {  // requests never carry the exception bit: keep it raw
        pdu.violations.add(FindingCode::PduUnknownFunction);
        auto data = r.rest();
        pdu.body = RawPdu{{data.begin(), data.end()}};
        return pdu;
    }
    return decode_request_body(std::move(pdu), r);
}

Result<Pdu> decode_response(std::span<const std::uint8_t> bytes) noexcept {
    ByteReader r(bytes);
    auto fc = r.u8();
    if (!fc) return make_error(ErrorCode::EmptyPdu, 0);
    Pdu pdu;
    pdu.function_raw = *fc;
    pdu.direction = Direction::Response;
    return decode_response_body(std::move(pdu), r);
}

Result<Pdu> decode_pdu(std::span<const std::uint8_t> bytes, Direction direction) noexcept {
    if (direction == Direction::Request) return decode_request(bytes);
    if (direction == Direction::Response) return decode_response(bytes);
    auto request = decode_request(bytes);
    if (request && request->violations.empty()) return request;
    auto response = decode_response(bytes);
    if (response && (response->violations.empty() || !request)) return response;
    if (request) return request;
    return response;
}

// ---------------------------------------------------------------- encoding

namespace {

void put16(std::vector<std::uint8_t>& out, std::uint16_t v) {
    out.push_back(static_cast<std::uint8_t>(v >> 8));
    out.push_back(static_cast<std::uint8_t>(v & 0xFF));
}
void put_words(std::vector<std::uint8_t>& out, const std::vector<std::uint16_t>& words) {
    for (auto w : words)
        put16(out, w);
}

struct BodyEncoder {
    std::vector<std::uint8_t>& out;
    void operator()(const RawPdu& b) { out.insert(out.end(), b.data.begin(), b.data.end()); }
    void operator()(const ReadRequest& b) {
        put16(out, b.starting_address);
        put16(out, b.quantity);
    }
    void operator()(const WriteSingle& b) {
        put16(out, b.address);
        put16(out, b.value);
    }
    void operator()(const NoData&) {}
    void operator()(const Diagnostics& b) {
        put16(out, b.sub_function);
        out.insert(out.end(), b.data.begin(), b.data.end());
    }
    void operator()(const WriteMultipleCoilsRequest& b) {
        put16(out, b.starting_address);
        put16(out, b.quantity);
        out.push_back(b.byte_count);
        out.insert(out.end(), b.values.begin(), b.values.end());
    }
    void operator()(const WriteMultipleRegistersRequest& b) {
        put16(out, b.starting_address);
        put16(out, b.quantity);
        out.push_back(b.byte_count);
        put_words(out, b.values);
    }
    void operator()(const FileRecordRequest& b) {
        out.push_back(b.byte_count);
        for (const auto& s : b.sub_requests) {
            out.push_back(s.reference_type);
            put16(out, s.file_number);
            put16(out, s.record_number);
            put16(out, s.record_length);
            put_words(out, s.record_data);
        }
    }
    void operator()(const MaskWriteRegister& b) {
        put16(out, b.reference_address);
        put16(out, b.and_mask);
        put16(out, b.or_mask);
    }
    void operator()(const ReadWriteMultipleRequest& b) {
        put16(out, b.read_starting_address);
        put16(out, b.quantity_to_read);
        put16(out, b.write_starting_address);
        put16(out, b.quantity_to_write);
        out.push_back(b.write_byte_count);
        put_words(out, b.write_values);
    }
    void operator()(const ReadFifoQueueRequest& b) { put16(out, b.fifo_pointer_address); }
    void operator()(const ReadDeviceIdRequest& b) {
        out.push_back(mei_read_device_identification);
        out.push_back(b.read_device_id_code);
        out.push_back(b.object_id);
    }
    void operator()(const MeiTransport& b) {
        out.push_back(b.mei_type);
        out.insert(out.end(), b.data.begin(), b.data.end());
    }
    void operator()(const ReadBitsResponse& b) {
        out.push_back(b.byte_count);
        out.insert(out.end(), b.values.begin(), b.values.end());
    }
    void operator()(const ReadRegistersResponse& b) {
        out.push_back(b.byte_count);
        put_words(out, b.values);
    }
    void operator()(const ReadExceptionStatusResponse& b) { out.push_back(b.output_data); }
    void operator()(const CommEventCounterResponse& b) {
        put16(out, b.status);
        put16(out, b.event_count);
    }
    void operator()(const CommEventLogResponse& b) {
        out.push_back(b.byte_count);
        put16(out, b.status);
        put16(out, b.event_count);
        put16(out, b.message_count);
        out.insert(out.end(), b.events.begin(), b.events.end());
    }
    void operator()(const WriteMultipleResponse& b) {
        put16(out, b.starting_address);
        put16(out, b.quantity);
    }
    void operator()(const ReportServerIdResponse& b) {
        out.push_back(b.byte_count);
        out.insert(out.end(), b.data.begin(), b.data.end());
    }
    void operator()(const ReadFileRecordResponse& b) {
        out.push_back(b.byte_count);
        for (const auto& s : b.sub_responses) {
            out.push_back(s.length);
            out.push_back(s.reference_type);
            put_words(out, s.record_data);
        }
    }
    void operator()(const ReadFifoQueueResponse& b) {
        put16(out, b.byte_count);
        put16(out, b.fifo_count);
        put_words(out, b.values);
    }
    void operator()(const ReadDeviceIdResponse& b) {
        out.push_back(mei_read_device_identification);
        out.push_back(b.read_device_id_code);
        out.push_back(b.conformity_level);
        out.push_back(b.more_follows);
        out.push_back(b.next_object_id);
        out.push_back(b.number_of_objects);
        for (const auto& o : b.objects) {
            out.push_back(o.id);
            out.push_back(static_cast<std::uint8_t>(o.value.size()));
            out.insert(out.end(), o.value.begin(), o.value.end());
        }
    }
    void operator()(const ExceptionResponse& b) { out.push_back(b.exception_code); }
};

}  // namespace

void encode_pdu_into(const Pdu& pdu, std::vector<std::uint8_t>& out) {
    out.push_back(pdu.function_raw);
    std::visit(BodyEncoder{out}, pdu.body);
}

std::vector<std::uint8_t> encode_pdu(const Pdu& pdu) {
    std::vector<std::uint8_t> out;
    out.reserve(8);
    encode_pdu_into(pdu, out);
    return out;
}

// ---------------------------------------------------------------- builders

namespace {
Pdu make(std::uint8_t fc, Direction d, PduBody body) {
    Pdu p;
    p.function_raw = fc;
    p.direction = d;
    p.body = std::move(body);
    return p;
}
std::uint8_t raw(FunctionCode fc) {
    return static_cast<std::uint8_t>(fc);
}
}  // namespace

std::vector<std::uint8_t> pack_bits(std::span<const bool> bits) {
    std::vector<std::uint8_t> packed((bits.size() + 7) / 8, 0);
    for (std::size_t i = 0; i < bits.size(); ++i)
        if (bits[i]) packed[i / 8] = static_cast<std::uint8_t>(packed[i / 8] | (1u << (i % 8)));
    return packed;
}

bool padding_bits_set(std::span<const std::uint8_t> packed, std::uint16_t quantity) noexcept {
    const unsigned used = quantity % 8;
    if (packed.empty() || used == 0 || packed.size() != (quantity + 7u) / 8u) return false;
    return (packed.back() >> used) != 0;
}

bool bit_at(std::span<const std::uint8_t> packed, std::size_t index) noexcept {
    if (index / 8 >= packed.size()) return false;
    return (packed[index / 8] >> (index % 8)) & 1u;
}

Pdu make_read_request(FunctionCode fc, std::uint16_t starting_address, std::uint16_t quantity) {
    return make(raw(fc), Direction::Request, ReadRequest{starting_address, quantity});
}
Pdu make_write_single_coil(std::uint16_t address, bool on) {
    return make(raw(FunctionCode::WriteSingleCoil), Direction::Request,
                WriteSingle{address, static_cast<std::uint16_t>(on ? 0xFF00 : 0x0000)});
}
Pdu make_write_single_register(std::uint16_t address, std::uint16_t value) {
    return make(raw(FunctionCode::WriteSingleRegister), Direction::Request, WriteSingle{address, value});
}
Pdu make_write_multiple_coils(std::uint16_t starting_address, std::span<const bool> values) {
    auto packed = pack_bits(values);
    return make(raw(FunctionCode::WriteMultipleCoils), Direction::Request,
                WriteMultipleCoilsRequest{starting_address, static_cast<std::uint16_t>(values.size()),
                                          static_cast<std::uint8_t>(packed.size()), std::move(packed)});
}
Pdu make_write_multiple_registers(std::uint16_t starting_address, std::span<const std::uint16_t> values) {
    return make(raw(FunctionCode::WriteMultipleRegisters), Direction::Request,
                WriteMultipleRegistersRequest{starting_address,
                                              static_cast<std::uint16_t>(values.size()),
                                              static_cast<std::uint8_t>(values.size() * 2),
                                              {values.begin(), values.end()}});
}
Pdu make_read_write_multiple(std::uint16_t read_start, std::uint16_t read_quantity, std::uint16_t write_start,
                             std::span<const std::uint16_t> values) {
    return make(raw(FunctionCode::ReadWriteMultipleRegisters), Direction::Request,
                ReadWriteMultipleRequest{read_start,
                                         read_quantity,
                                         write_start,
                                         static_cast<std::uint16_t>(values.size()),
                                         static_cast<std::uint8_t>(values.size() * 2),
                                         {values.begin(), values.end()}});
}
Pdu make_diagnostics(std::uint16_t sub_function, std::span<const std::uint8_t> data) {
    return make(raw(FunctionCode::Diagnostics), Direction::Request,
                Diagnostics{sub_function, {data.begin(), data.end()}});
}
Pdu make_mask_write_register(std::uint16_t address, std::uint16_t and_mask, std::uint16_t or_mask) {
    return make(raw(FunctionCode::MaskWriteRegister), Direction::Request,
                MaskWriteRegister{address, and_mask, or_mask});
}
Pdu make_read_fifo_queue(std::uint16_t fifo_pointer_address) {
    return make(raw(FunctionCode::ReadFifoQueue), Direction::Request,
                ReadFifoQueueRequest{fifo_pointer_address});
}
Pdu make_read_device_id(std::uint8_t read_device_id_code, std::uint8_t object_id) {
    return make(raw(FunctionCode::EncapsulatedInterface), Direction::Request,
                ReadDeviceIdRequest{read_device_id_code, object_id});
}
Pdu make_no_data_request(FunctionCode fc) {
    return make(raw(fc), Direction::Request, NoData{});
}
Pdu make_read_bits_response(FunctionCode fc, std::span<const bool> values) {
    auto packed = pack_bits(values);
    const auto bc = static_cast<std::uint8_t>(packed.size());
    return make(raw(fc), Direction::Response, ReadBitsResponse{bc, std::move(packed)});
}
Pdu make_read_registers_response(FunctionCode fc, std::span<const std::uint16_t> values) {
    return make(
        raw(fc), Direction::Response,
        ReadRegistersResponse{static_cast<std::uint8_t>(values.size() * 2), {values.begin(), values.end()}});
}
Pdu make_write_multiple_response(FunctionCode fc, std::uint16_t starting_address, std::uint16_t quantity) {
    return make(raw(fc), Direction::Response, WriteMultipleResponse{starting_address, quantity});
}
Pdu make_exception(std::uint8_t function_code, std::uint8_t exception_code) {
    return make(static_cast<std::uint8_t>(function_code | exception_bit), Direction::Response,
                ExceptionResponse{exception_code});
}

}  // namespace mbscope::modbus
