#pragma once
// One Modbus server unit: a profile, its register image and the rules of its manual, applied in the order
// the specification prescribes (AP V1.1b3 §6 state diagrams: function code → quantity → address → value →
// execution). A Device sees PDUs only; framing, unit routing and wire-level faults are the server's.
//
// Where a manual is silent the specification decides; where the profile records a manual's deviation
// (MK's 15-register and 30-coil limits, Walchem's first-address-only check and FC1/FC2, FC3/FC4 sameness,
// CTH2265I's 0x55AA reserved registers) the profile wins.

#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "modbus/pdu.hpp"
#include "modbus/profile.hpp"
#include "slave/faults.hpp"
#include "slave/register_image.hpp"

namespace mbscope::slave {

// FC8 and FC11 counters (AP §6.8, SL §6.1). The server reports framing errors; the device counts the rest.
struct Counters {
    std::uint16_t bus_messages = 0;     // every frame seen on the line, CRC good or bad, any unit
    std::uint16_t bus_comm_errors = 0;  // CRC/LRC errors
    std::uint16_t exceptions = 0;       // exception responses sent
    std::uint16_t server_messages = 0;  // requests addressed to this unit (or broadcast)
    std::uint16_t no_response = 0;      // requests not answered (broadcasts, listen-only)
    std::uint16_t overruns = 0;         // requests longer than the device takes (AP §6.8.1 0x12)
    std::uint16_t event_count = 0;      // FC11: successful completions, polls and diagnostics excluded
    std::uint16_t diagnostic_register = 0;
};

struct Request {
    std::span<const std::uint8_t> pdu;
    bool broadcast = false;
};

struct Reply {
    std::vector<std::uint8_t> pdu;  // empty: no answer
    bool wrote = false;             // the request changed the register image (the state file must be saved)
};

class Device {
  public:
    Device(const modbus::Profile& profile, std::uint8_t unit, FaultSet* faults = nullptr);
    // Served on `line`: the registers that mirror its settings read them (MK-CFG-01, CTH-ADR-01).
    Device(const modbus::Profile& profile, const modbus::LineState& line, FaultSet* faults = nullptr);

    Reply handle(const Request& request);
    void count_frame(bool checksum_ok) noexcept;  // the server saw a frame on the line (any unit)
    // The reply to a write whose effect was taken back (it could not be saved): exception 04, counted as an
    // exception and not as a completed message (FC11 counts successful completions only, AP §6.9).
    std::vector<std::uint8_t> refuse_taken_back_write(std::uint8_t fc);
    // After the image's undo() of a write handle() executed (a broadcast that could not be saved): not
    // counted as a completion, and a new address taken back with it.
    void take_back_write() noexcept;
    // As the device was made: initial register image, counters zero, not in listen-only mode.
    void reset() noexcept;

    RegisterImage& image() noexcept { return image_; }
    const RegisterImage& image() const noexcept { return image_; }
    const modbus::Profile& profile() const noexcept { return *profile_; }
    const FaultSet& faults() const noexcept { return *faults_; }
    // The address the device answers at now: the one it was made with until a write to the register that
    // holds its address moves it (MK ENDER: the device obeys at once, MK-CFG-01; 0 disables communication,
    // MK-ADR-01), as a restored state file can.
    std::uint8_t unit() const noexcept { return unit_; }
    // The address it was made with (`--unit`), which names it in a state file whatever it answers at now.
    std::uint8_t configured_unit() const noexcept { return configured_unit_; }
    // Takes the address the image holds in the register that mirrors it, when the map has a writable one and
    // the value is an address (0-255): after a write the server took back, and after a state file was
    // applied.
    void follow_address() noexcept;
    // The framing, baud rate and parity the device holds in the registers that mirror them (MK PROT, BAUD,
    // PARID; unknown where the map mirrors none or the code means nothing), and those its image was made
    // with. They differ once a master wrote another valid code: the device then talks with the new
    // settings, which the server follows (MK-CFG-01).
    modbus::LineState held_line() const;
    modbus::LineState made_line() const;
    // Off the line: its settings differ from those of the line other units keep, so it cannot read a frame
    // on it and answers nothing; back when the line takes its settings, or at reset().
    void leave_line() noexcept { off_line_ = true; }
    void join_line() noexcept { off_line_ = false; }
    bool off_line() const noexcept { return off_line_; }
    const Counters& counters() const noexcept { return counters_; }
    bool listen_only() const noexcept { return listen_only_; }
    // Addresses whose value the process must not move (stuck-value fault, or a user's pinned value).
    bool frozen(modbus::Table t, std::uint16_t address) const noexcept;

  private:
    std::vector<std::uint8_t> exception(std::uint8_t fc, std::uint8_t code);
    std::vector<std::uint8_t> dispatch(const modbus::Pdu& req, bool broadcast, bool& wrote);
    // Rules: nullopt passes, otherwise the exception code.
    std::optional<std::uint8_t> check_quantity(std::uint8_t fc, std::uint32_t quantity,
                                               bool write_part = false);
    std::optional<std::uint8_t> check_write_block(modbus::Table t, std::uint16_t start,
                                                  const std::vector<std::uint16_t>& values);
    std::uint16_t read_word(modbus::Table t, std::uint16_t address) const noexcept;
    void write_words(modbus::Table t, std::uint16_t start, const std::vector<std::uint16_t>& values);
    // The register of the image that holds what a master calls `address`: itself, or under word-swap the
    // other register of its 32-bit value. Reads and writes both go through it, so a device with the wrong
    // word order is wrong the same way both ways (what it answers, written back, restores the value).
    std::uint16_t stored_address(modbus::Table t, std::uint16_t address) const noexcept;
    // A write as the image takes it: each value at its stored_address(), the block spanning them. A half of
    // a 32-bit value the block leaves out can move past the block's edge; the registers the write does not
    // set keep what the image holds (`written` false), so the value is judged whole with its other half.
    struct StoredBlock {
        std::uint16_t start = 0;
        std::vector<std::uint16_t> values;
        std::vector<bool> written;
    };
    StoredBlock as_stored(modbus::Table t, std::uint16_t start,
                          const std::vector<std::uint16_t>& values) const;
    std::uint16_t served(std::uint16_t address) const noexcept;  // off-by-one-address fault
    std::uint16_t acknowledged(std::uint16_t quantity);          // wrong-quantity fault

    std::vector<std::uint8_t> read_bits(const modbus::Pdu& req);
    std::vector<std::uint8_t> read_registers(const modbus::Pdu& req);
    std::vector<std::uint8_t> write_single_coil(const modbus::Pdu& req, bool& wrote);
    std::vector<std::uint8_t> write_single_register(const modbus::Pdu& req, bool& wrote);
    std::vector<std::uint8_t> write_multiple_coils(const modbus::Pdu& req, bool& wrote);
    std::vector<std::uint8_t> write_multiple_registers(const modbus::Pdu& req, bool& wrote);
    std::vector<std::uint8_t> mask_write(const modbus::Pdu& req, bool& wrote);
    std::vector<std::uint8_t> read_write_multiple(const modbus::Pdu& req, bool& wrote);
    std::vector<std::uint8_t> diagnostics(const modbus::Pdu& req);
    std::vector<std::uint8_t> read_fifo(const modbus::Pdu& req);
    std::vector<std::uint8_t> read_device_id(const modbus::Pdu& req);
    std::vector<std::uint8_t> report_server_id();

    const modbus::Profile* profile_;
    std::uint8_t unit_;
    std::uint8_t configured_unit_;
    FaultSet* faults_;
    FaultSet no_faults_;
    RegisterImage image_;
    const modbus::Point* address_register_;  // Profile::address_register()
    Counters counters_;
    bool listen_only_ = false;
    bool off_line_ = false;
};

}  // namespace mbscope::slave
