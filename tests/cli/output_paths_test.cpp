// Output paths are checked before a long run: `mbscope check` writes its reports at the end of a
// certification (minutes on a bench slave, tens of minutes on a controller), `mbscope fuzz` its reproducers
// whenever a finding comes. A path that cannot be written stops the command at once with exit code 2, before
// the target is even reached (the targets here are unreachable: had the check come later, the message would
// be "cannot reach the target").
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "tests/cli/cli_run.hpp"

namespace test_cli_output_paths_test {

namespace {

using mbscope::test::run_mbscope;

const std::string unreachable = " --target tcp://127.0.0.1:1 --profile mmk-2030 ";

}  // namespace

TEST(OutputPaths, CheckRefusesReportsItCouldNotWriteBeforeTheRun) {
    const std::string dir = ::testing::TempDir() + "mbscope-output-paths";
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    const struct {
        std::string option, path, why;
    } cases[] = {
        {"--junit", dir + "/missing/check.xml", dir + "/missing/check.xml: no directory " + dir + "/missing"},
        {"--report", dir, dir + ": is a directory"},
        {"--html", dir + "/missing/check.html", "no directory"},
    };
    for (const auto& c : cases) {
        const auto r = run_mbscope("check" + unreachable + c.option + " " + c.path);
        EXPECT_EQ(r.exit_code, 2) << r.out;
        EXPECT_NE(r.out.find("mbscope check: cannot write " + c.path), std::string::npos) << r.out;
        EXPECT_NE(r.out.find(c.why), std::string::npos) << r.out;
        EXPECT_EQ(r.out.find("cannot reach the target"), std::string::npos) << r.out;
    }
    // A writable one is no reason to stop: the run goes on to the target (unreachable here), and the file
    // says so (CheckCommand.AnUnreachableTargetIsReportedInEveryFileAskedFor).
    const auto fine = run_mbscope("check" + unreachable + "--junit " + dir + "/check.xml");
    EXPECT_EQ(fine.exit_code, 2) << fine.out;
    EXPECT_NE(fine.out.find("cannot reach the target"), std::string::npos) << fine.out;
    EXPECT_TRUE(std::filesystem::exists(dir + "/check.xml"));
}

TEST(OutputPaths, FuzzMakesItsArtifactsDirectoryFirstOrStops) {
    const std::string dir = ::testing::TempDir() + "mbscope-output-paths-fuzz";
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    std::ofstream(dir + "/file") << "x";
    const auto blocked =
        run_mbscope("fuzz" + unreachable + "--requests 10 --artifacts " + dir + "/file/artifacts");
    EXPECT_EQ(blocked.exit_code, 2) << blocked.out;
    EXPECT_NE(blocked.out.find("mbscope fuzz: --artifacts " + dir + "/file/artifacts: "), std::string::npos)
        << blocked.out;
    EXPECT_EQ(blocked.out.find("cannot reach the target"), std::string::npos) << blocked.out;
    const auto made =
        run_mbscope("fuzz" + unreachable + "--requests 10 --artifacts " + dir + "/new/artifacts");
    EXPECT_EQ(made.exit_code, 2) << made.out;
    EXPECT_NE(made.out.find("cannot reach the target"), std::string::npos) << made.out;
    EXPECT_TRUE(std::filesystem::is_directory(dir + "/new/artifacts"));
}

}  // namespace test_cli_output_paths_test
