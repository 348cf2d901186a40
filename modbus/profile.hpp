#pragma once
// Device profiles, resolved: one Profile per device id (model), with the base map of its manual section, the
// model's exclusions and overrides applied and, for modular devices, the configuration's maps expanded.
// The data format is documented in profiles/README.md; this is its in-memory model and the queries every
// part of mbscope asks of it: what is at (table, address), what do these raw words mean, would the device
// accept this write.

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "modbus/addressing.hpp"
#include "modbus/formula.hpp"
#include "modbus/serial_line.hpp"  // LineState

namespace mbscope::modbus {

enum class Access : std::uint8_t { Read = 1, Write = 2, ReadWrite = 3 };
std::string_view to_string(Access a) noexcept;

enum class EncodingType : std::uint8_t {
    U16,
    S16,
    Fixed,
    Scaled,
    Enum,
    AsciiChar,
    Digits4High,
    Digits4Low,
    U32,
    S32,
    F32,
    U32Low,
    U32High,
    Bytes2,
    Bits,
    Status,
    Bool,
    Formula,
};
std::string_view to_string(EncodingType t) noexcept;
std::optional<EncodingType> parse_encoding_type(std::string_view name) noexcept;

enum class WordOrder : std::uint8_t { Abcd, Badc, Cdab, Dcba };
std::string_view to_string(WordOrder w) noexcept;
std::optional<WordOrder> parse_word_order(std::string_view name) noexcept;

// The 32-bit value held in the registers at an address (first) and the next (second), and back.
std::uint32_t join_words(std::uint16_t first, std::uint16_t second, WordOrder order) noexcept;
std::array<std::uint16_t, 2> split_words(std::uint32_t value, WordOrder order) noexcept;

struct PointRef {
    Table table = Table::HoldingRegisters;
    std::uint16_t address = 0;
};

// Scaled: the register that gives the decimals, chosen by the value another register holds. TY-2090's
// retransmission limits take the engineering unit, and so the PT.DEC register, of the input register 27 or 28
// associates with the output (000:627): selector 27, 0 → register 17, 1 → register 18.
struct DecimalsChoice {
    PointRef selector;
    std::vector<std::pair<std::int64_t, PointRef>> by_value;
};

struct EnumValue {
    std::int64_t value = 0;
    std::string text;
    std::string text_en;
    // On a point that mirrors a line setting, the setting this code stands for: "rtu" or "ascii", a baud
    // rate ("9600"), "none", "even" or "odd".
    std::string means;
    // Listed by the manual as a value the register does not take ("não permitido", DCY-2050 Light's input
    // types 2 and 4, 000:1097): shown with its text when read, refused when written.
    bool forbidden = false;
};

struct BitName {
    std::uint8_t bit = 0;
    std::string name;
    std::string name_en;
};

// Bytes2: one of the two 8-bit fields of a register.
struct ByteField {
    std::string name;    // the manual's, "?" where it does not say which byte holds which field
    bool ascii = false;  // an ASCII character ("8 bits ascii": CTH2265I TAG, 003:634-637)
};

struct Encoding {
    EncodingType type = EncodingType::U16;
    int decimals = 0;
    bool is_signed = false;
    std::optional<PointRef> decimals_from;            // Scaled
    std::optional<DecimalsChoice> decimals_selected;  // Scaled, instead of decimals_from
    // U32Low/High: the decimal point is one 8-bit field of this register, which one the manual does not say
    // (CTH2265I 4010, 4020, 4026: 003:578-581, 620, 626); known only when both bytes hold the same.
    std::optional<PointRef> decimals_from_byte;
    // A value whose decimal point the manual puts in no register it names (CTH2265I 4006-4007): why, shown
    // with the unscaled value.
    std::string decimals_unknown;
    std::vector<EnumValue> values;      // Enum, Status
    std::string allowed;                // AsciiChar
    std::optional<std::uint16_t> pair;  // Digits4*, U32Low/High: address of the other half
    WordOrder word_order = WordOrder::Abcd;
    int words = 1;              // 2 for 32-bit values held in this and the next register
    std::vector<BitName> bits;  // Bits
    std::string expr;           // Formula, as the manual gives it
    Formula formula;            // Formula: expr, parsed
    // Bytes2: the high byte's field, then the low byte's; `values` and `bits` apply to each byte.
    std::array<ByteField, 2> bytes;
};

// The raw values a point's register or registers can hold: 0..65535 (-32768..32767 signed) for one
// register, the 32-bit ranges for two, 0..1 for a bit. nullopt for a float, whose range is given in
// engineering units.
struct RawLimits {
    std::int64_t min = 0;
    std::int64_t max = 0;
};
std::optional<RawLimits> raw_limits(const Encoding& e) noexcept;

// A line setting a register reads back (MK-CFG-01: ENDER, PROT, BAUD and PARID mirror the front panel's
// RS level; CTH-ADR-01: register 3999 holds the configured address).
enum class LineSetting : std::uint8_t { UnitId, Framing, Baud, Parity };
std::string_view to_string(LineSetting s) noexcept;  // "unit_id", "framing", "baud", "parity"
std::optional<LineSetting> parse_line_setting(std::string_view text) noexcept;

struct Point {
    Table table = Table::HoldingRegisters;
    std::uint16_t address = 0;
    std::string name;     // the manual's words
    std::string name_en;  // short English name
    std::string mnemonic;
    Access access = Access::Read;
    Encoding encoding;
    std::optional<std::int64_t> min, max;  // raw units (two's complement values as signed numbers)
    std::optional<PointRef> min_from, max_from;
    // Read-only while the point `when` holds one of `values` (MK: a control output in automatic mode,
    // 000:731; a program's repetitions while it runs, 000:737): the manual's conditional access, applied by
    // the reference slave with the state it holds.
    struct ReadOnlyWhen {
        PointRef when;
        std::vector<std::uint16_t> values;
    };
    std::optional<ReadOnlyWhen> read_only_when;
    std::string range_text;
    std::string range_source;  // where range_text comes from when a model override replaced it (a footnote)
    std::string unit;
    std::optional<std::uint16_t> fixed_value;
    bool reserved = false;
    // A write-1-to-act command (Walchem "Gravar 1 para ...", 002:412-417 call them reset buttons): a write
    // acts on the device, and no later write undoes it, so a run that restores what it wrote must not write
    // it.
    bool momentary = false;
    bool reconstructed = false;
    std::string reconstructed_why;  // the profile's reason and the lines it was reconstructed from
    std::string source;             // "000:493"
    std::vector<std::string> notes;
    std::string ref;  // the manual's printed reference when it differs from the address
    std::optional<LineSetting> mirrors;
    // A point of an alternative map (Walchem 5.3.9): it reads what the holding register at this address
    // holds (and the next, for a two-register value), its object's own field, rather than a value of its
    // own.
    std::optional<std::uint16_t> same_value_as;
};

// What a point mirroring a line setting reads under `line`: the unit id itself, or the code the map gives
// the setting. nullopt when the point mirrors nothing, when the line has no such setting (a baud rate over
// TCP) or when the map has no code for it.
std::optional<std::uint16_t> mirrored_value(const Point& p, const LineState& line);
// On a point mirroring a line setting, the value the map gives `code` when it means a setting ("ascii",
// "9600", "even"); null for a code the manual does not define or that means none.
const EnumValue* mirrored_meaning(const Point& p, std::uint16_t code);

struct ProfileNote {
    std::string text;
    std::string source;
    std::string kind;  // contradiction, typo, damage, implied, info
};

struct LineRules {
    std::vector<std::string> transports;  // rtu, ascii, tcp
    std::vector<std::uint32_t> baud_rates;
    std::vector<std::string> parity;
    int unit_min = 1;
    int unit_max = 247;
    std::vector<int> unit_disabled;
    // Whether a device at `unit` does not communicate (MK's address 0, MK-ADR-01).
    bool disables(int unit) const noexcept {
        return std::find(unit_disabled.begin(), unit_disabled.end(), unit) != unit_disabled.end();
    }
    bool any_unit_answered = false;  // Walchem: every non-zero unit id is answered (002:213-215)
    int tcp_port = 502;
    std::optional<int> min_poll_interval_ms;
    std::optional<int> response_timeout_ms;
    int ascii_inter_char_timeout_ms = 1000;
    // The longest PDU the device takes: the specification's 253 (AP §4.1), or what its manual says
    // (Walchem: 2 to 256 bytes, 002:219, against the specification). A longer request cannot reach it over
    // a serial line (an RTU ADU of 256 bytes holds 253); over Modbus/TCP it can, and is not handled: a
    // character overrun (AP §6.8.1, sub-function 0x12), not a request.
    std::size_t pdu_max_bytes = 253;
    // The character the manual fixes: data bits per framing ("rtu", "ascii"), and the stop bits it allows
    // per framing and parity ("rtu", "rtu_parity", "rtu_no_parity", "ascii", ...): MK-CHR-01, MK-CHR-02.
    std::map<std::string, int, std::less<>> data_bits;
    std::map<std::string, std::vector<int>, std::less<>> stop_bits;
    // What they fix for a line: nullopt where the manual says nothing, or allows several stop bits.
    std::optional<int> data_bits_for(Framing framing) const;
    std::optional<int> stop_bits_for(Framing framing, Parity parity) const;
    // The stop bits the manual allows there (the most specific key); null where it says nothing.
    const std::vector<int>* stop_bits_allowed(Framing framing, Parity parity) const;
    // `line` with the character that goes with `framing` and its parity: the manual's (MK-CHR-01: 8 data
    // bits in RTU, 7 in ASCII; MK-CHR-02: 2 stop bits in ASCII without parity, else 1), else the
    // specification's data bits (SL §2.5.1, §2.5.2) and the stop bits as they were. For a line told another
    // framing or parity.
    SerialLine character_for(Framing framing, SerialLine line) const;
};

// How a line departs from what the device's manual allows (transports, baud rates, parities, data and stop
// bits), a sentence each; `line` for a serial line, null over TCP. Empty when it departs in nothing the
// manual states.
std::vector<std::string> line_departures(const LineRules& rules, Framing framing, const SerialLine* line);

enum class AddressCheck : std::uint8_t { Every, First };

struct FunctionRules {
    std::vector<std::uint8_t> supported;
    std::map<std::string, int> max_quantity;  // "3" → 15, "23w" → 121
    std::vector<std::uint8_t> broadcast;
    std::vector<std::uint16_t> diagnostics;
    AddressCheck address_check = AddressCheck::Every;
    // condition → code (nullopt: the manual is silent). Looked up by a literal (exception_for) on every
    // refused request: std::less<> finds it without making a string of it.
    std::map<std::string, std::optional<int>, std::less<>> exceptions;
    std::set<std::string, std::less<>> implied_exceptions;  // conditions whose code the manual only implies

    bool supports(std::uint8_t fc) const;
    bool allows_broadcast(std::uint8_t fc) const;  // the manual runs it sent to unit 0 (SL §2.1)
    // The manual's limit, else the specification's (AP §6.x); 0 when the function has no quantity.
    int max_for(std::uint8_t fc, bool write_part = false) const;
};

// The process behind a device, for the reference slave: what moves, and how. Not part of any manual (a
// manual describes the instrument, not the plant it measures); each profile says which points are its
// process values, totals and alarm outputs and why. Values are raw register values (engineering units
// times the point's decimal scaling); time runs in fixed steps.
struct SimulationSignal {
    enum class Model : std::uint8_t {
        Walk,       // a measured value: mean-reverting random walk around `start`, within [min, max]
        Integrate,  // a total: accumulates `per_second` x the source's value each second (wraps at `max`)
        Alarm,      // an alarm output: trips past the setpoint, releases past setpoint -/+ hysteresis
        Constant,   // a value the device reports and never changes (a firmware version): `start`
    };
    std::string id;
    Model model = Model::Walk;
    PointRef point;  // where the value is written (a two-register point: both words, in its word order)
    // No point ("point" left out, `point` unused): a quantity the device measures but its map does not show
    // (the pulse rate an -FCS totalizer counts); the signals that follow it see it all the same.
    bool hidden = false;
    double start = 0, min = 0, max = 0;
    double step = 0;                               // Walk: standard deviation of the change per second
    std::string of;                                // Integrate, Alarm: the signal they follow
    double per_second = 0;                         // Integrate
    std::optional<PointRef> setpoint, hysteresis;  // Alarm: read from the image, so writes take effect
    bool high = true;                              // Alarm: trips above the setpoint (false: below)
    // Modular devices: the signal exists only where the configuration gives these channels these maps (the
    // same address is another channel's field, or no field, in other configurations).
    std::map<std::string, std::string> configuration;
};

struct Simulation {
    std::string source;  // why these points: the manual lines that name them
    std::vector<SimulationSignal> signals;
};

struct Profile {
    std::string id;  // model id, lower case
    std::string name;
    std::vector<std::string> aliases;
    std::string family;
    std::string vendor;
    std::string title;
    std::string file;    // where it was loaded from
    std::string source;  // manual and section
    LineRules line;
    FunctionRules functions;
    bool open_address_space = false;  // generic profile: every address exists
    // Walchem: coil-accessible fields are holding registers seen as bits; a coil reads 1 when the register at
    // its address is non-zero and FC5 writes 1 or 0 into that register (002:244, 493).
    bool coils_view_registers = false;
    Simulation simulation;  // the process the reference slave runs behind the map (empty: values stay)
    std::vector<ProfileNote> notes;
    // The orders a device can be set to send its 32-bit values in, the default first (Walchem's "inverse"
    // data format, a menu setting, 002:470-477); empty where the manual gives one order.
    std::vector<WordOrder> word_orders;
    bool modular = false;                              // channels whose maps a configuration chooses
    std::map<std::string, std::string> configuration;  // modular devices: channel → map

    // Points per table, sorted by address. A table that serves another one's map (MK FC3/FC4, Walchem
    // FC1/FC2 and FC3/FC4) holds no points of its own and names it in same_as.
    std::array<std::vector<Point>, 5> points;  // indexed by Table's value (0, 1, 3, 4)
    std::array<std::optional<Table>, 5> same_as;
    std::array<bool, 5> has_table{};

    Table resolve(Table t) const noexcept;
    const std::vector<Point>& table(Table t) const noexcept { return points[static_cast<int>(resolve(t))]; }
    bool implements(Table t) const noexcept { return has_table[static_cast<int>(t)]; }
    // The point holding `address` (a 32-bit point holds two addresses); nullptr when the map has none.
    const Point* find(Table t, std::uint16_t address) const noexcept;
    // The holding register a master may write that holds the device's own address (MK ENDER: the device
    // obeys a new one at once, MK-CFG-01); nullptr when the map has none.
    const Point* address_register() const noexcept;
    std::size_t point_count(Table t) const noexcept { return points[static_cast<int>(t)].size(); }
};

// ---- queries

struct NamedValue {
    const Point* point = nullptr;  // nullptr: address not in the map
    std::uint16_t address = 0;
    std::vector<std::uint16_t> raw;  // the register(s) the value was built from
    std::optional<double> number;    // scaled numeric value; none when partial (its text says why)
    std::string text;                // enumeration text, characters, bits, or the number formatted
    bool partial = false;  // a 32-bit or paired value whose other half, or a scaled one whose decimal
                           // point register, is outside the block and not known from elsewhere
    // A 32-bit or paired value whose other half is outside the block, taken from an earlier reply (or
    // write) of the device: that register's address. The value is whole only if that half has not
    // changed since; the text says so.
    std::optional<std::uint16_t> other_half_earlier;
};

// The settings a device whose holding registers read `read` holds, as far as its map mirrors them
// (framing, baud rate, parity: mirrored_value's inverse; not the unit, which the caller knows). A code the
// map gives no meaning leaves that setting unknown.
LineState held_line_settings(const Profile& profile, const std::function<std::uint16_t(std::uint16_t)>& read);
// Sets in `state` the setting a mirrored point's code means (mirrored_meaning's "ascii", "9600", "even").
void take_meaning(LineState& state, LineSetting setting, const std::string& means);

// Reads the profile's 32-bit values in `order` (every one in its default order) when its manual lets the
// device be set to it: nothing when done or when the profile maps nothing (the generic one), else why not
// (a map without 32-bit values included).
std::optional<std::string> set_word_order(Profile& profile, WordOrder order);

// Shortest text that reads back as the same float ("1.5", "0.000123", "1e-10", "nan", "-inf").
std::string float_text(float f);

// Registers known from outside a block, by table: a 32-bit value's other half, a decimal point register. The
// input registers are apart from the holding registers unless the profile makes them one map (same_as, as
// MK's): input register 11 of a device with two maps is no half of holding register 10.
struct RegisterContext {
    std::map<std::uint16_t, std::uint16_t> holding = {};
    std::map<std::uint16_t, std::uint16_t> input = {};  // kept apart from `holding` only (resolve())
};

// Decode a block of raw registers read from `start` (FC3/FC4 reply) into named, scaled values.
// `context` supplies registers outside the block, may be empty. Words past address 65535 get no value (they
// are not wrapped round to address 0).
std::vector<NamedValue> decode_registers(const Profile& profile, Table table, std::uint16_t start,
                                         const std::vector<std::uint16_t>& words,
                                         const RegisterContext& context = {});

// Would the device accept reading `quantity` items from `start` in table `t` (FC1-FC4, FC23's read part)?
// nullopt: yes; otherwise the profile's code for a bad address (02 unless the manual gives another): an
// address past 65535, a table the device does not implement, or an address the map lacks (only the first
// one when the manual says the device checks only that). The quantity itself is not judged here.
std::optional<std::uint8_t> check_read(const Profile& profile, Table t, std::uint16_t start,
                                       std::uint32_t quantity);

// Would the device accept writing `value` at `address`? nullopt: yes; otherwise the exception code the
// profile says it answers (02 for an address the map lacks or a read-only point where the manual gives
// none, 03 for a value outside the documented range or enumeration).
std::optional<std::uint8_t> check_write(const Profile& profile, Table table, std::uint16_t address,
                                        std::uint16_t value);

struct WriteRejection {
    std::uint8_t exception_code = 0;
    std::uint16_t address = 0;  // the first offending address
    std::string reason;  // "address not in the map", "read-only point", "value 1500 above maximum 1440"
};

// Would the device accept writing `values` from `start` (FC6, FC16, FC23's write part; FC5 and FC15 with one
// value per coil, 0 or 1)? Applies the specification's order: every address first (exception 02, only the
// first one when the profile says the device checks only that), then every value (exception 03). A 32-bit
// point whose two registers are both in the block is checked as one value (floats against their range in
// engineering units). A lone half of it is checked with the other half the device holds, when `held` says
// (a slave knows its registers: Walchem's manual tells clients to write a 32-bit set-point's halves with
// FC6, 002:499, and each write must leave the whole value within range and a number); without `held` it is
// not range-checked.
std::optional<WriteRejection> check_writes(
    const Profile& profile, Table table, std::uint16_t start, const std::vector<std::uint16_t>& values,
    const std::function<std::optional<std::uint16_t>(std::uint16_t)>& held = {});

// The exception code the profile gives for a condition ("bad_address", "bad_value", "bad_quantity",
// "unsupported_function", "write_read_only"), or the specification's when the manual is silent.
std::uint8_t exception_for(const Profile& profile, const char* condition, std::uint8_t specification_default);

}  // namespace mbscope::modbus
