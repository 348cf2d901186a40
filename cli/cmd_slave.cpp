// mbscope slave: serve device profiles over TCP, UDP, serial framing over TCP, a serial port or a
// pseudo-terminal, with planted faults on demand.
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <memory>

#include "cli/commands.hpp"
#include "cli/number_checks.hpp"
#include "cli/output_paths.hpp"
#include "cli/profile_json.hpp"
#include "cli/stop_signal.hpp"
#include "modbus/frame_text.hpp"
#include "modbus/storage/profile_store.hpp"
#include "modbus/transport/endpoint.hpp"
#include "slave/faults.hpp"
#include "slave/process.hpp"
#include "slave/server.hpp"
#include "slave/state_file.hpp"

namespace mbscope::cli {
namespace {

// Where a device answers: "address 5", or that it is silent (an address its manual says disables
// communication, MK's 0).
std::string address_text(const slave::Device& d) {
    if (d.profile().line.disables(d.unit()))
        return "address " + std::to_string(d.unit()) + ", which disables communication";
    return "address " + std::to_string(d.unit());
}

struct SlaveOptions {
    std::string profile = "modbus";
    std::string listen = "tcp://127.0.0.1:5020";
    std::vector<std::string> units;
    std::string state;
    std::uint64_t seed = 1;
    std::vector<std::string> faults;
    std::vector<std::string> profile_dirs;
    std::vector<std::string> config;
    bool pty = false;
    bool quiet = false;
    double idle_timeout_s = 60;
    std::size_t max_clients = 1024;
};

int run_slave(SlaveOptions o) {  // a copy: --state is resolved
    // Before the profiles load: a signal from here on stops the slave as one while it serves does (exit 0,
    // its counts said), not by killing it.
    const auto& stop = stop_on_signals(BrokenPipe::Ignored);
    auto endpoint = modbus::transport::parse_endpoint(o.listen);
    if (!endpoint) {
        std::cerr << "mbscope slave: " << modbus::printable(endpoint.error()) << '\n';
        return exit_failure;
    }
    // A fault given twice is refused unless both instances act (stuck-value at two registers): every
    // fault announced as planted below acts.
    const auto parsed = slave::parse_faults(o.faults);
    if (!parsed) {
        std::cerr << "mbscope slave: " << parsed.error() << '\n';
        return exit_failure;
    }
    const std::vector<slave::FaultSpec>& specs = parsed.value();
    for (const auto& f : specs)
        if (const auto why =
                slave::fault_without_effect(f.fault, modbus::transport::framing_of(endpoint->scheme))) {
            std::cerr << "mbscope slave: --fault " << to_string(f.fault) << " has no effect on "
                      << endpoint->text() << ": " << *why << '\n';
            return exit_failure;
        }
    const auto config = parse_config_options(o.config, "slave");
    if (!config) return exit_failure;
    const auto store = open_profile_store(o.profile_dirs, "slave");
    if (!store) return exit_failure;
    // --unit N or N=PROFILE; without --unit, unit 1 with --profile.
    std::vector<std::pair<int, std::string>> wanted;
    for (const auto& u : o.units) {
        const auto eq = u.find('=');
        const std::string number = u.substr(0, eq);
        char* end = nullptr;
        const long n = std::strtol(number.c_str(), &end, 10);
        if (number.empty() || *end != '\0' || n < 0 || n > 255) {
            std::cerr << "mbscope slave: --unit takes 0..255 or N=PROFILE, not '" << u << "'\n";
            return exit_failure;
        }
        for (const auto& [m, id] : wanted)
            if (m == n) {
                std::cerr << "mbscope slave: unit " << n << " given twice\n";
                return exit_failure;
            }
        wanted.emplace_back(static_cast<int>(n), eq == std::string::npos ? o.profile : u.substr(eq + 1));
    }
    if (wanted.empty()) wanted.emplace_back(1, o.profile);
    std::vector<std::string> ids;
    for (const auto& [unit, id] : wanted)
        ids.push_back(id);
    if (!config_is_for_a_modular_device(*store, ids, *config, "slave")) return exit_failure;

    std::vector<std::unique_ptr<modbus::Profile>> profiles;
    std::vector<std::unique_ptr<slave::Device>> devices;
    std::vector<slave::Process> processes;
    slave::FaultSet faults(specs, o.seed);
    for (const auto& [unit, id] : wanted) {
        auto p = store->load(id, *config);
        if (!p) {
            for (const auto& e : p.error())
                std::cerr << "mbscope slave: " << modbus::to_string(e) << '\n';
            return exit_failure;
        }
        // The manual's address range (MK: 1..99, 000:269; the specification: 1..247).
        const bool disables = p->line.disables(unit);
        if (unit == 0 && !disables) {
            std::cerr << "mbscope slave: unit 0 is the broadcast address; " << p->id
                      << "'s manual gives it no other meaning\n";
            return exit_failure;
        }
        if (disables && !o.quiet)
            std::cerr << "mbscope slave: unit " << unit << " disables communication on " << p->id
                      << " (its manual says so): the device will not answer\n";
        if (unit < p->line.unit_min || unit > p->line.unit_max) {
            std::cerr << "mbscope slave: unit " << unit << " is outside " << p->id << "'s address range "
                      << p->line.unit_min << ".." << p->line.unit_max << '\n';
            return exit_failure;
        }
        profiles.push_back(std::make_unique<modbus::Profile>(std::move(p.value())));
        // What the registers mirroring the line read: the framing served, and on a serial line its speed
        // and parity.
        devices.push_back(std::make_unique<slave::Device>(
            *profiles.back(), modbus::transport::line_state(*endpoint, static_cast<std::uint8_t>(unit)),
            &faults));
    }
    std::vector<slave::Device*> units;
    for (auto& d : devices)
        units.push_back(d.get());
    for (std::size_t i = 0; i < devices.size(); ++i)
        processes.emplace_back(*devices[i], o.seed + i);
    slave::ServerOptions options;
    modbus::transport::UniqueFd state_lock;  // held until the slave stops
    if (std::error_code ec; !o.state.empty() && std::filesystem::is_symlink(o.state, ec)) {
        // A link's file is the one kept: saved by a rename over the path, the link became a file of its own
        // and the file it named stayed as it was; and a slave given the file's own name, whose lock file is
        // named after it, was not refused beside one given the link.
        if (auto target = std::filesystem::canonical(o.state, ec); !ec) o.state = target.string();
    }
    if (!o.state.empty()) {
        // Saved as a file beside it, renamed over it: a directory that cannot take it would make every
        // write fail (exception 04) from the first one on.
        if (const auto why = cannot_write_file(o.state + ".tmp")) {
            std::cerr << "mbscope slave: --state " << o.state << ": cannot be saved (" << *why << ")\n";
            return exit_failure;
        }
        auto lock = slave::lock_state(o.state);
        if (!lock) {
            std::cerr << "mbscope slave: --state " << lock.error() << '\n';
            return exit_failure;
        }
        state_lock = std::move(lock.value());
        auto loaded = slave::load_state(o.state, units);
        if (!loaded) {
            std::cerr << "mbscope slave: " << loaded.error() << '\n';
            return exit_failure;
        }
        options.state_others = std::move(loaded.value());
        if (!o.quiet && options.state_others.is_object())
            for (const auto& [unit, saved] : options.state_others.items())
                std::cerr << "mbscope slave: " << o.state << ": unit " << unit
                          << " is not served now; its saved values stay in the file\n";
    }
    options.state_file = o.state;
    options.create_pty = o.pty;
    options.max_clients = o.max_clients;
    options.idle_timeout = std::chrono::milliseconds(static_cast<long>(o.idle_timeout_s * 1000));
    // A write to a device's address register moves it at once (MK ENDER): said as it happens.
    std::vector<std::uint8_t> answering;
    for (const auto* d : units)
        answering.push_back(d->unit());
    options.tick = [&processes, &units, &answering,
                    quiet = o.quiet](std::chrono::steady_clock::time_point now) {
        for (auto& p : processes)
            p.advance(now);
        for (std::size_t i = 0; i < units.size(); ++i) {
            if (units[i]->unit() == answering[i]) continue;
            answering[i] = units[i]->unit();
            if (!quiet)
                std::cerr << "mbscope slave: unit " << int(units[i]->configured_unit()) << " ("
                          << units[i]->profile().id << ") now answers at " << address_text(*units[i])
                          << ": its address register was written\n";
        }
    };
    // So do PROT, BAUD and PARID: the line follows a device alone on it.
    options.on_line_change = [quiet = o.quiet](const std::string& text) {
        if (!quiet) std::cerr << "mbscope slave: " << text << '\n';
    };
    if (o.pty && !modbus::transport::is_serial(endpoint->scheme)) {
        std::cerr << "mbscope slave: --pty needs a serial endpoint (rtu:pty or ascii:pty)\n";
        return exit_failure;
    }
    slave::Server server(*endpoint, units, faults, options);
    if (auto opened = server.open(); !opened) {
        std::cerr << "mbscope slave: " << opened.error() << '\n';
        return exit_failure;
    }
    run_begins();
    // The address first and alone on stdout, so scripts and tests can read where to connect.
    std::cout << server.address() << std::endl;
    if (!o.quiet) {
        const auto served = server.endpoint();  // a state file's line settings included
        const bool serial = modbus::transport::is_serial(served.scheme);
        // A serial address printed is a device path (what libmodbus and pyserial open); the mbscope commands
        // want it with its scheme and line settings, which the path alone does not carry.
        if (serial) {
            auto target = served;
            target.device = server.address();
            std::cerr << "mbscope slave: mbscope commands reach it as --target '" << target.text() << "'\n";
        }
        for (const auto* d : units) {
            std::cerr << "mbscope slave: unit " << int(d->configured_unit()) << " serves " << d->profile().id;
            if (d->unit() != d->configured_unit())
                std::cerr << ", answering at " << address_text(*d) << " (its address register, as " << o.state
                          << " keeps it)";
            std::cerr << '\n';
            // Served as asked, but said: a tester who meant to reproduce the device would not pick these.
            for (const auto& departure :
                 modbus::line_departures(d->profile().line, modbus::transport::framing_of(served.scheme),
                                         serial ? &served.line : nullptr))
                std::cerr << "mbscope slave: unit " << int(d->configured_unit()) << " (" << d->profile().id
                          << "): " << departure << "; served as given\n";
        }
        for (const auto& f : o.faults)
            std::cerr << "mbscope slave: planted fault " << f << '\n';
    }
    auto ran = server.run(stop);
    if (!ran) {
        std::cerr << "mbscope slave: " << ran.error() << '\n';
        return exit_failure;
    }
    const auto& s = server.stats();
    if (!o.quiet)
        std::cerr << "mbscope slave: " << s.requests << " requests, " << s.responses << " responses, "
                  << s.bad_frames << " bad frames, " << s.connections << " connections\n";
    return exit_ok;
}

}  // namespace

void register_slave(CLI::App& app, int& exit_code) {
    auto o = std::make_shared<SlaveOptions>();
    auto* cmd =
        app.add_subcommand("slave", "Serve device profiles as a Modbus slave, faults planted on demand");
    cmd->footer(
        "Endpoints:\n"
        "  tcp://HOST:PORT  udp://HOST:PORT  rtu-tcp://HOST:PORT  ascii-tcp://HOST:PORT\n"
        "  'rtu:DEVICE?baud=9600&parity=E&stop=1'   'ascii:DEVICE?...'   (quoted: ? and & are the shell's;\n"
        "  --pty: rtu:pty creates a pseudo-terminal)\n"
        "The address clients connect to is printed on stdout (the real port when PORT is 0, the pty's "
        "path);\nfor a serial one, standard error also gives the --target that check, fuzz and replay "
        "take.\n\n"
        "Units (a multi-drop line is several devices on one endpoint):\n"
        "  --unit 1=cth2265i --unit 2=mmk-2030 --unit 3   each unit with its own profile (3: --profile's)\n"
        "  A unit no --unit names gets no reply, on every transport (the slave is no gateway). Unit 0 is\n"
        "  the broadcast: every unit whose profile allows the function executes it, none replies. Over\n"
        "  tcp with a single unit, unit 255 reaches it too (Modbus/TCP: the device is its IP address),\n"
        "  and so does any unit when its manual says so (Walchem). A valid write to a device's address\n"
        "  register (MK ENDER) moves it at once, after its acknowledgement; --state keeps the move.\n\n"
        "Faults (--fault NAME[=ARG], repeatable, deterministic under --seed):\n" +
        slave::fault_help() +
        "  A fault tied to one framing (bad-crc, bad-lrc, wrong-tid, the protocol id ones, "
        "gap-inside-frame)\n"
        "  is refused on an endpoint whose frames have nothing for it to change.\n"
        "  Each fault is given once (one delay, one code, one rate), stuck-value once per register.\n"
        "\nExit codes: 0 stopped by SIGINT/SIGTERM/SIGHUP, 2 could not start (bad option, profile, endpoint, "
        "fault or state file).");
    cmd->add_option("--profile", o->profile,
                    "Device profile id or alias for the units (default: modbus, the generic one)");
    cmd->add_option("--listen", o->listen, "Endpoint to serve (default tcp://127.0.0.1:5020)");
    cmd->add_option("--unit", o->units, "Unit id to serve, N or N=PROFILE (repeatable; default 1)");
    cmd->add_option("--state", o->state,
                    "Keep the register image in FILE across restarts (saved atomically on every write)");
    cmd->add_option("--seed", o->seed, "Seed of the simulated process and of fault rates (default 1)")
        ->check(seed_value());
    cmd->add_option("--fault", o->faults, "Plant a fault, NAME[=ARG] (repeatable; see below)");
    cmd->add_option("--profile-dir", o->profile_dirs, "Extra directory of profile files (repeatable)");
    cmd->add_option("--config", o->config, "Modular devices: CHANNEL=MAP (repeatable)");
    cmd->add_flag("--pty", o->pty, "Serial endpoint: create a pseudo-terminal and print its path");
    cmd->add_option("--idle-timeout", o->idle_timeout_s,
                    "Seconds before a silent TCP client is disconnected (default 60)")
        ->check(finite_between(0.001, 86400, "seconds"));
    cmd->add_option("--max-clients", o->max_clients, "Concurrent TCP clients (default 1024)")
        ->check(CLI::Range(std::size_t{1}, std::size_t{65536}));
    cmd->add_flag("--quiet,-q", o->quiet, "No messages on stderr");
    cmd->callback([o, &exit_code] { exit_code = run_slave(*o); });
}

}  // namespace mbscope::cli
