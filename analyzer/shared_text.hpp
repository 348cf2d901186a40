#pragma once
// An immutable string shared by every record that names the same thing. A capture of a million frames
// names a few links, sources and devices a million times; each frame record used to carry its own copies
// (two allocations a frame for "10.0.0.1:40000 -> 10.1.0.1:502" and "10.1.0.1:502 unit 3"). Copying a
// SharedText is a reference count, and records kept beyond the analysis (tests keep them) stay valid.
// The count is not atomic (an analysis and its records belong to one thread: an atomic count was a tenth
// of a summary run): a record passed to another thread must be copied there with its texts as strings.

#include <memory>
#include <ostream>
#include <string>
#include <string_view>
#include <utility>

#include "modbus/json_writer.hpp"

namespace mbscope::analyzer {

class SharedText {
  public:
    SharedText() = default;
    SharedText(std::string text) : entry_(new Entry(std::move(text))) {}  // NOLINT: reads as the string
    SharedText(const char* text) : SharedText(std::string(text)) {}       // NOLINT
    SharedText(const SharedText& other) noexcept : entry_(other.entry_) {
        if (entry_) ++entry_->references;
    }
    SharedText(SharedText&& other) noexcept : entry_(other.entry_) { other.entry_ = nullptr; }
    SharedText& operator=(const SharedText& other) noexcept {
        SharedText copy(other);
        std::swap(entry_, copy.entry_);
        return *this;
    }
    SharedText& operator=(SharedText&& other) noexcept {
        std::swap(entry_, other.entry_);
        return *this;
    }
    ~SharedText() {
        if (entry_ && --entry_->references == 0) delete entry_;
    }

    const std::string& str() const noexcept { return entry_ ? entry_->text : empty_string(); }
    // Plain printable ASCII without quotes or backslashes: written into JSON as it is (checked once per
    // text, not once per record that names it).
    bool json_plain() const noexcept { return !entry_ || entry_->json_plain; }
    operator const std::string&() const noexcept { return str(); }  // NOLINT: reads as the string it is
    std::string_view view() const noexcept { return str(); }
    bool empty() const noexcept { return str().empty(); }
    std::size_t size() const noexcept { return str().size(); }

    friend bool operator==(const SharedText& a, const SharedText& b) noexcept {
        return a.entry_ == b.entry_ || a.str() == b.str();
    }
    friend bool operator==(const SharedText& a, std::string_view b) noexcept { return a.str() == b; }
    friend bool operator==(const SharedText& a, const std::string& b) noexcept { return a.str() == b; }
    friend bool operator==(const SharedText& a, const char* b) noexcept { return a.str() == b; }
    friend std::string operator+(const SharedText& a, std::string_view b) {
        return std::string(a.str()).append(b);
    }
    friend std::string operator+(std::string_view a, const SharedText& b) {
        return std::string(a).append(b.str());
    }
    friend std::ostream& operator<<(std::ostream& out, const SharedText& t) { return out << t.str(); }

  private:
    static const std::string& empty_string() noexcept {
        static const std::string empty;
        return empty;
    }
    struct Entry {
        explicit Entry(std::string t) : text(std::move(t)), json_plain(modbus::json_plain(text)) {}
        std::string text;
        bool json_plain;
        std::size_t references = 1;
    };
    Entry* entry_ = nullptr;
};

}  // namespace mbscope::analyzer
