// The README's worked examples stay what the binary prints: every `mbscope frame` and every `mbscope decode`
// of a bundled capture shown there with its output is run, and each line of that output must appear in what
// it prints now ("..." stands for lines left out). The decode example had drifted from the binary twice.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "tests/cli/cli_run.hpp"

namespace test_cli_readme_examples_test {

namespace {

struct Example {
    std::string command;  // after "$ mbscope ", its comment taken off
    std::vector<std::string> output;
};

std::string trimmed(const std::string& s) {
    const auto first = s.find_first_not_of(' ');
    const auto last = s.find_last_not_of(' ');
    return first == std::string::npos ? std::string() : s.substr(first, last - first + 1);
}

// The examples of the README's shell blocks that show their output.
std::vector<Example> readme_examples() {
    std::ifstream in(std::string(MBSCOPE_SOURCE_DIR) + "/README.md");
    std::vector<Example> examples;
    bool in_block = false;
    Example* current = nullptr;
    for (std::string line; std::getline(in, line);) {
        if (line.starts_with("```")) {
            in_block = line == "```sh";
            current = nullptr;
            continue;
        }
        if (!in_block) continue;
        if (line.starts_with("$ ")) {
            current = nullptr;
            const std::string prefix = "$ mbscope ";
            if (!line.starts_with(prefix)) continue;
            std::string command = line.substr(prefix.size());
            command = trimmed(command.substr(0, command.find(" # ")));
            if (command.starts_with("frame ") || command.starts_with("decode captures/")) {
                examples.push_back({command, {}});
                current = &examples.back();
            }
            continue;
        }
        if (!current) continue;
        const std::string expected = trimmed(line);
        if (!expected.empty() && expected != "...") current->output.push_back(line);
    }
    return examples;
}

}  // namespace

TEST(ReadmeExamples, TheOutputShownIsWhatTheBinaryPrints) {
    const auto examples = readme_examples();
    std::size_t shown = 0;
    for (const auto& e : examples) {
        if (e.output.empty()) continue;
        ++shown;
        const auto r = mbscope::test::run_mbscope(e.command, "cd " + std::string(MBSCOPE_SOURCE_DIR) + " &&");
        std::vector<std::string> printed;
        std::istringstream lines(r.out);
        for (std::string line; std::getline(lines, line);)
            printed.push_back(line);
        for (const auto& line : e.output)  // whole lines: "functions:" is not "functions: FC43×2"
            EXPECT_NE(std::find(printed.begin(), printed.end(), line), printed.end())
                << "README: mbscope " << e.command << "\nshows: " << line << "\nthe binary prints:\n"
                << r.out;
    }
    EXPECT_GE(shown, 3u);  // the FC3 request, the bad CRC, the suricata capture
}

}  // namespace test_cli_readme_examples_test
