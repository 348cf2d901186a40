#pragma once
// One checked cursor over a byte span. Every read is bounds-checked and returns std::optional; there is no
// unchecked skip, and the cursor always knows its offset (used in DecodeError). Big-endian, as Modbus is.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>

namespace mbscope::modbus {

class ByteReader {
  public:
    explicit ByteReader(std::span<const std::uint8_t> bytes) noexcept : bytes_(bytes) {}

    std::size_t offset() const noexcept { return pos_; }
    std::size_t remaining() const noexcept { return bytes_.size() - pos_; }
    bool empty() const noexcept { return pos_ == bytes_.size(); }

    std::optional<std::uint8_t> u8() noexcept {
        if (remaining() < 1) return std::nullopt;
        return bytes_[pos_++];
    }
    std::optional<std::uint16_t> u16() noexcept {
        if (remaining() < 2) return std::nullopt;
        auto v = static_cast<std::uint16_t>((bytes_[pos_] << 8) | bytes_[pos_ + 1]);
        pos_ += 2;
        return v;
    }
    std::optional<std::span<const std::uint8_t>> take(std::size_t n) noexcept {
        if (remaining() < n) return std::nullopt;
        auto s = bytes_.subspan(pos_, n);
        pos_ += n;
        return s;
    }
    std::span<const std::uint8_t> rest() noexcept {
        auto s = bytes_.subspan(pos_);
        pos_ = bytes_.size();
        return s;
    }

  private:
    std::span<const std::uint8_t> bytes_;
    std::size_t pos_ = 0;
};

}  // namespace mbscope::modbus
