#pragma once
// The data a slave serves: its four tables as the device holds them. Tables a profile declares the same as
// another (MK FC3/FC4, Walchem FC1/FC2 and FC3/FC4) share storage, so a write through one is read through the
// other; Walchem coils are views of the holding registers at the same address (profile.coils_view_registers),
// and its alternative maps' registers views of their objects' own fields (Point::same_value_as).
// Initial values follow the map: fixed read values (CTH2265I 0x55AA), an enumeration's first value, a
// range's minimum when zero is outside it (floats encoded in the profile's word order).

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "modbus/profile.hpp"

namespace mbscope::slave {

using modbus::Table;

class RegisterImage {
  public:
    // With `line`, the points that mirror a line setting (MK ENDER/PROT/BAUD/PARID, CTH register 3999)
    // start at the settings the device is served with.
    explicit RegisterImage(const modbus::Profile& profile,
                           std::optional<modbus::LineState> line = std::nullopt);

    std::uint16_t reg(Table t, std::uint16_t address) const noexcept;
    // A holding register's value in the image construction made (before any write).
    std::uint16_t initial_holding(std::uint16_t address) const noexcept;
    void set_reg(Table t, std::uint16_t address, std::uint16_t value) noexcept;
    bool bit(Table t, std::uint16_t address) const noexcept;
    void set_bit(Table t, std::uint16_t address, bool value) noexcept;

    // 32-bit values of two-register points, in the point's word order.
    std::uint32_t u32(Table t, std::uint16_t address, modbus::WordOrder order) const noexcept;
    void set_u32(Table t, std::uint16_t address, std::uint32_t value, modbus::WordOrder order) noexcept;
    void set_f32(Table t, std::uint16_t address, float value, modbus::WordOrder order) noexcept;
    float f32(Table t, std::uint16_t address, modbus::WordOrder order) const noexcept;

    // Every address whose value differs from the initial image, per table: what a state file keeps.
    std::map<Table, std::map<std::uint16_t, std::uint16_t>> changes() const;
    const modbus::Profile& profile() const noexcept { return *profile_; }
    // How many stores changed a value since construction: equal counts mean an unchanged image (a cheap
    // test of "this request changed nothing", the fuzz oracle's and the state file's question).
    std::uint64_t modifications() const noexcept { return modifications_; }
    // Back to the image construction made: the pages written since are dropped, the initial ones shared
    // again, the modification count is zero. Costs the pages written, not the map (the fuzz target resets
    // one image per input instead of building it again).
    void reset() noexcept;

    // Stores made after begin_undo() can be taken back: a write the slave cannot save to its state file is
    // answered with exception 04, and a refused request must leave the registers as they were (AP §7).
    // undo() restores them (and the modification count), keep() forgets them; either ends the journal.
    void begin_undo();
    void undo() noexcept;
    void keep() noexcept;

  private:
    // Each table is 256 pages of 256 words. A page nobody wrote since the image was made is shared with the
    // initial image (all-zero pages with one static page); a write copies its page first. Making an image
    // costs the pages the map initialises, not 64 Ki words per table (what made the slave fuzz target
    // spend most of its time zeroing and copying memory), and changes() looks at written pages only.
    static constexpr std::size_t page_words = 256;
    static constexpr std::size_t page_count = 65536 / page_words;
    using Page = std::array<std::uint16_t, page_words>;
    struct Words {
        std::array<const Page*, page_count> page{};           // what reads see
        std::array<std::unique_ptr<Page>, page_count> own{};  // pages written since the initial image
    };
    Words& words(Table t) noexcept;
    const Words& words(Table t) const noexcept;
    std::uint16_t& writable(Words& w, std::uint16_t address);
    void initialise();

    // The holding registers that read another (alternative maps), by page: what reg() and set_reg() look
    // through, at the cost of one test for the pages that have none.
    std::uint16_t seen_through(const Words& w, std::uint16_t address) const noexcept;
    std::array<bool, page_count> aliased_page_{};
    std::vector<std::pair<std::uint16_t, std::uint16_t>> aliases_;  // sorted: address → the one it reads

    const modbus::Profile* profile_;
    std::optional<modbus::LineState> line_;
    // Indexed by the resolved table's value; bits are kept one per word for simple, uniform storage.
    Words tables_[5];
    std::array<const Page*, page_count> initial_[5]{};
    std::vector<std::unique_ptr<const Page>> initial_pages_;      // the initial image's non-zero pages
    std::vector<std::pair<std::uint8_t, std::uint8_t>> written_;  // (table, page) of every own page
    std::uint64_t modifications_ = 0;
    struct Stored {
        std::uint16_t* word;  // in an own page: kept until reset(), which ends any journal first
        std::uint16_t before;
    };
    bool journaling_ = false;
    std::vector<Stored> journal_;
    std::uint64_t modifications_before_ = 0;
};

}  // namespace mbscope::slave
