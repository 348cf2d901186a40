// mbscope: Modbus analyzer, conformance runner, reference slave and fuzzer, one binary with subcommands.
#include <iostream>

#include "cli/commands.hpp"

namespace {

// A repeatable option takes one value each time it is given: CLI11's vector options take every argument up
// to the next option, so `mbscope decode --tcp-port 5020 plant.pcap` read the capture's name as a port, and
// `--map 1=mmk-2030 plant.pcap` left no file. Positionals (files, frame bytes) still take all.
void one_value_per_repeatable_option(CLI::App& app) {
    for (CLI::Option* opt : app.get_options([](const CLI::Option* o) { return o->nonpositional(); }))
        if (opt->get_expected_max() > 1) {
            opt->expected(1);
            opt->allow_extra_args(false);
            opt->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
        }
    for (CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
        one_value_per_repeatable_option(*sub);
}

}  // namespace

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
    one_value_per_repeatable_option(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        const int rc = app.exit(e);
        // --help and --version exit 0; usage errors are "could not run" (2), not "findings" (1).
        return rc == 0 ? 0 : mbscope::cli::exit_failure;
    }
    return exit_code;
}
