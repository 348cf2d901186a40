#include "slave/register_image.hpp"

#include <algorithm>
#include <cstring>

namespace mbscope::slave {

namespace {
int index_of(Table t) noexcept {
    return static_cast<int>(t);
}
}  // namespace

namespace {
const std::array<std::uint16_t, 256> zero_page{};
}  // namespace

RegisterImage::RegisterImage(const modbus::Profile& profile, std::optional<modbus::LineState> line)
    : profile_(&profile), line_(line) {
    for (auto& w : tables_)
        w.page.fill(&zero_page);
    for (const modbus::Point& p : profile.table(Table::HoldingRegisters)) {
        if (!p.same_value_as) continue;
        for (int w = 0; w < p.encoding.words; ++w) {
            const auto address = static_cast<std::uint16_t>(p.address + w);
            aliases_.emplace_back(address, static_cast<std::uint16_t>(*p.same_value_as + w));
            aliased_page_[address / page_words] = true;
        }
    }
    std::sort(aliases_.begin(), aliases_.end());
    initialise();
    // What initialise() wrote becomes the initial image, shared by every page until it is written again.
    for (int i = 0; i < 5; ++i) {
        for (std::size_t p = 0; p < page_count; ++p)
            if (tables_[i].own[p]) initial_pages_.push_back(std::move(tables_[i].own[p]));
        initial_[i] = tables_[i].page;
    }
    written_.clear();
    modifications_ = 0;  // initialise() stored through set_reg; a new image has changed nothing yet
}

void RegisterImage::reset() noexcept {
    keep();
    for (const auto& [table, page] : written_) {
        tables_[table].own[page].reset();
        tables_[table].page[page] = initial_[table][page];
    }
    written_.clear();
    modifications_ = 0;
}

RegisterImage::Words& RegisterImage::words(Table t) noexcept {
    if (t == Table::Coils && profile_->coils_view_registers) t = Table::HoldingRegisters;
    if (t == Table::DiscreteInputs && profile_->coils_view_registers &&
        profile_->resolve(Table::DiscreteInputs) == Table::Coils)
        t = Table::HoldingRegisters;
    return tables_[index_of(profile_->resolve(t))];
}

const RegisterImage::Words& RegisterImage::words(Table t) const noexcept {
    return const_cast<RegisterImage*>(this)->words(t);
}

std::uint16_t& RegisterImage::writable(Words& w, std::uint16_t address) {
    const std::size_t p = address / page_words;
    if (!w.own[p]) {
        w.own[p] = std::make_unique<Page>(*w.page[p]);
        w.page[p] = w.own[p].get();
        written_.emplace_back(static_cast<std::uint8_t>(&w - tables_), static_cast<std::uint8_t>(p));
    }
    return (*w.own[p])[address % page_words];
}

std::uint16_t RegisterImage::seen_through(const Words& w, std::uint16_t address) const noexcept {
    if (!aliased_page_[address / page_words] || &w != &tables_[index_of(Table::HoldingRegisters)])
        return address;
    const auto it = std::lower_bound(aliases_.begin(), aliases_.end(),
                                     std::pair<std::uint16_t, std::uint16_t>{address, 0});
    return it != aliases_.end() && it->first == address ? it->second : address;
}

std::uint16_t RegisterImage::reg(Table t, std::uint16_t address) const noexcept {
    const Words& w = words(t);
    address = seen_through(w, address);
    return (*w.page[address / page_words])[address % page_words];
}
std::uint16_t RegisterImage::initial_holding(std::uint16_t address) const noexcept {
    address = seen_through(tables_[index_of(Table::HoldingRegisters)], address);
    return (*initial_[index_of(Table::HoldingRegisters)][address / page_words])[address % page_words];
}
void RegisterImage::set_reg(Table t, std::uint16_t address, std::uint16_t value) noexcept {
    Words& w = words(t);
    address = seen_through(w, address);
    const std::uint16_t before = (*w.page[address / page_words])[address % page_words];
    if (before == value) return;
    std::uint16_t& word = writable(w, address);
    if (journaling_) journal_.push_back({&word, before});
    word = value;
    ++modifications_;
}

void RegisterImage::begin_undo() {
    journal_.clear();
    journaling_ = true;
    modifications_before_ = modifications_;
}

void RegisterImage::undo() noexcept {
    for (auto it = journal_.rbegin(); it != journal_.rend(); ++it)
        *it->word = it->before;
    if (journaling_) modifications_ = modifications_before_;
    keep();
}

void RegisterImage::keep() noexcept {
    journal_.clear();
    journaling_ = false;
}
bool RegisterImage::bit(Table t, std::uint16_t address) const noexcept {
    return reg(t, address) != 0;
}
void RegisterImage::set_bit(Table t, std::uint16_t address, bool value) noexcept {
    set_reg(t, address, value ? 1 : 0);
}

std::uint32_t RegisterImage::u32(Table t, std::uint16_t address, modbus::WordOrder order) const noexcept {
    return modbus::join_words(reg(t, address), reg(t, static_cast<std::uint16_t>(address + 1)), order);
}

void RegisterImage::set_u32(Table t, std::uint16_t address, std::uint32_t value,
                            modbus::WordOrder order) noexcept {
    const auto w = modbus::split_words(value, order);
    set_reg(t, address, w[0]);
    set_reg(t, static_cast<std::uint16_t>(address + 1), w[1]);
}

void RegisterImage::set_f32(Table t, std::uint16_t address, float value, modbus::WordOrder order) noexcept {
    std::uint32_t u;
    std::memcpy(&u, &value, sizeof u);
    set_u32(t, address, u, order);
}

float RegisterImage::f32(Table t, std::uint16_t address, modbus::WordOrder order) const noexcept {
    const std::uint32_t u = u32(t, address, order);
    float f;
    std::memcpy(&f, &u, sizeof f);
    return f;
}

void RegisterImage::initialise() {
    using modbus::EncodingType;
    for (Table t : {Table::Coils, Table::DiscreteInputs, Table::InputRegisters, Table::HoldingRegisters}) {
        if (profile_->resolve(t) != t) continue;
        if (t == Table::Coils && profile_->coils_view_registers)
            continue;  // the registers' values are the coils'
        for (const modbus::Point& p : profile_->table(t)) {
            const modbus::Encoding& e = p.encoding;
            if (p.same_value_as) continue;  // its object's field holds its value
            if (p.fixed_value) {
                set_reg(t, p.address, *p.fixed_value);
                continue;
            }
            std::int64_t v = 0;
            // The first value listed that the register takes: one the manual does not allow, listed first,
            // made a device that refused to be written back to its own starting value.
            if (e.type == EncodingType::Enum || e.type == EncodingType::Status)
                if (const auto first = std::find_if(e.values.begin(), e.values.end(),
                                                    [](const auto& ev) { return !ev.forbidden; });
                    first != e.values.end())
                    v = first->value;
            // A character point starts as a character it allows (MK TAG characters: 000:493 (i)), not NUL.
            if (e.type == EncodingType::AsciiChar && !e.allowed.empty())
                v = static_cast<unsigned char>(e.allowed.find('A') != std::string::npos ? 'A'
                                                                                        : e.allowed.front());
            if (p.min && *p.min > 0) v = *p.min;
            if (p.max && *p.max < 0) v = *p.max;
            if (line_)
                if (const auto mirrored = modbus::mirrored_value(p, *line_)) v = *mirrored;
            if (e.words == 2) {
                if (e.type == EncodingType::F32)
                    set_f32(t, p.address, static_cast<float>(v), e.word_order);
                else
                    set_u32(t, p.address, static_cast<std::uint32_t>(v), e.word_order);
            } else {
                set_reg(t, p.address, static_cast<std::uint16_t>(v));
            }
        }
    }
}

std::map<Table, std::map<std::uint16_t, std::uint16_t>> RegisterImage::changes() const {
    std::map<Table, std::map<std::uint16_t, std::uint16_t>> out;
    for (Table t : {Table::Coils, Table::DiscreteInputs, Table::InputRegisters, Table::HoldingRegisters}) {
        const Words& now = tables_[index_of(t)];
        for (std::size_t p = 0; p < page_count; ++p) {
            if (!now.own[p]) continue;  // unwritten: the initial page itself
            const Page& then = *initial_[index_of(t)][p];
            for (std::size_t i = 0; i < page_words; ++i)
                if ((*now.own[p])[i] != then[i])
                    out[t][static_cast<std::uint16_t>(p * page_words + i)] = (*now.own[p])[i];
        }
    }
    return out;
}

}  // namespace mbscope::slave
