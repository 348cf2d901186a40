#pragma once
// Result<T, E>: a value or an error, returned by every parser that sees hostile input.
// GCC 12 in C++20 mode has no std::expected; this mirrors its member names (has_value, value, error)
// so it can be replaced by std::expected later without touching call sites.

#include <cassert>
#include <cstdint>
#include <string_view>
#include <utility>
#include <variant>

namespace mbscope::modbus {

// Why a structure could not be recovered. One enumerator per distinct cause; to_string gives the message.
enum class ErrorCode : std::uint8_t {
    Truncated = 1,           // fewer bytes than the structure needs
    TrailingBytes = 2,       // more bytes than the structure holds
    ByteCountMismatch = 3,   // a byte count field disagrees with the bytes present
    ChecksumMismatch = 4,    // CRC or LRC does not match (ADU decoders only)
    BadStartCharacter = 5,   // ASCII frame does not start with ':'
    BadEndCharacters = 6,    // ASCII frame does not end with CR LF
    BadHexDigit = 7,         // ASCII frame holds a character that is not a hex digit
    OddHexLength = 8,        // ASCII frame holds an odd number of hex digits
    LengthFieldInvalid = 9,  // MBAP length outside 2..254 or not matching the bytes present
    TooLong = 10,            // longer than the specification's maximum ADU
    EmptyPdu = 11,           // no function code
    BadReference = 12,       // a reference number that names no table
    BadArgument = 13,        // an encoder was given a value that cannot be encoded
};

std::string_view to_string(ErrorCode code) noexcept;

struct DecodeError {
    ErrorCode code;
    std::uint32_t offset;  // byte offset from the start of the ADU (or PDU for PDU decoders)
};

template <class T, class E = DecodeError>
class Result {
  public:
    Result(T value) : v_(std::in_place_index<0>, std::move(value)) {}  // NOLINT: implicit on purpose
    Result(E error) : v_(std::in_place_index<1>, std::move(error)) {}  // NOLINT: implicit on purpose

    bool has_value() const noexcept { return v_.index() == 0; }
    explicit operator bool() const noexcept { return has_value(); }

    T& value() & {
        assert(has_value());
        return std::get<0>(v_);
    }
    const T& value() const& {
        assert(has_value());
        return std::get<0>(v_);
    }
    T&& value() && {
        assert(has_value());
        return std::get<0>(std::move(v_));
    }
    const E& error() const {
        assert(!has_value());
        return std::get<1>(v_);
    }
    T* operator->() { return &value(); }
    const T* operator->() const { return &value(); }
    T& operator*() & { return value(); }
    const T& operator*() const& { return value(); }

  private:
    std::variant<T, E> v_;
};

template <class E>
class Result<void, E> {
  public:
    Result() = default;
    Result(E error) : error_(std::move(error)), ok_(false) {}  // NOLINT: implicit on purpose
    bool has_value() const noexcept { return ok_; }
    explicit operator bool() const noexcept { return ok_; }
    const E& error() const {
        assert(!ok_);
        return error_;
    }

  private:
    E error_{};
    bool ok_ = true;
};

inline DecodeError make_error(ErrorCode code, std::size_t offset) noexcept {
    return DecodeError{code, static_cast<std::uint32_t>(offset)};
}

}  // namespace mbscope::modbus
