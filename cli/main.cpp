// mbscope: Modbus analyzer, conformance runner, reference slave and fuzzer, one binary with subcommands.
#include <iostream>

#include "cli/commands.hpp"

int main(int argc, char** argv) {
    CLI::App app{"mbscope " MBSCOPE_VERSION
                 " - make Modbus devices trustworthy: decode frames and captures, certify slaves, fuzz them"};
    app.require_subcommand(1);
    app.set_version_flag("--version", std::string("mbscope ") + MBSCOPE_VERSION);
    int exit_code = mbscope::cli::exit_ok;
    mbscope::cli::register_decode(app, exit_code);
    mbscope::cli::register_frame(app, exit_code);
    mbscope::cli::register_profile(app, exit_code);
    mbscope::cli::register_slave(app, exit_code);
    mbscope::cli::register_check(app, exit_code);
    mbscope::cli::register_sniff(app, exit_code);
    mbscope::cli::register_fuzz(app, exit_code);
    mbscope::cli::register_replay(app, exit_code);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        const int rc = app.exit(e);
        // --help and --version exit 0; usage errors are "could not run" (2), not "findings" (1).
        return rc == 0 ? 0 : mbscope::cli::exit_failure;
    }
    return exit_code;
}
