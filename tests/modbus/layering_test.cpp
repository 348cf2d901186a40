// The codec has no I/O: no file under modbus/ (outside modbus/transport/ and modbus/storage/) may include OS,
// socket, termios, pcap or iostream headers (conventions in shared/style.md, "Folder layout").
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace test_modbus_layering_test {

namespace fs = std::filesystem;

TEST(Layering, CodecIncludesNoIoHeaders) {
    const fs::path root = fs::path(MBSCOPE_SOURCE_DIR) / "modbus";
    const char* forbidden[] = {"<sys/",      "<termios.h>", "<pcap.h>",  "<pcap/",
                               "<iostream>", "<fstream>",   "<unistd.h>"};
    int files = 0;
    for (const auto& entry : fs::recursive_directory_iterator(root)) {
        if (!entry.is_regular_file()) continue;
        const auto rel = fs::relative(entry.path(), root).string();
        if (rel.rfind("transport", 0) == 0 || rel.rfind("storage", 0) == 0) continue;  // the I/O edges
        const auto ext = entry.path().extension();
        if (ext != ".cpp" && ext != ".hpp") continue;
        ++files;
        std::ifstream in(entry.path());
        std::string line;
        int n = 0;
        while (std::getline(in, line)) {
            ++n;
            if (line.find("#include") == std::string::npos) continue;
            for (const char* header : forbidden)
                EXPECT_EQ(line.find(header), std::string::npos) << rel << ":" << n << ": " << line;
        }
    }
    EXPECT_GT(files, 10);
}

TEST(Layering, PartsDependOnlyOnTheCodec) {
    // analyzer/, conformance/ and slave/ never include each other.
    const fs::path src(MBSCOPE_SOURCE_DIR);
    const char* parts[] = {"analyzer", "conformance", "slave"};
    for (const char* part : parts) {
        if (!fs::exists(src / part)) continue;
        for (const auto& entry : fs::recursive_directory_iterator(src / part)) {
            if (!entry.is_regular_file()) continue;
            std::ifstream in(entry.path());
            std::string line;
            while (std::getline(in, line)) {
                for (const char* other : parts) {
                    if (std::string(other) == part) continue;
                    EXPECT_EQ(line.find(std::string("#include \"") + other + "/"), std::string::npos)
                        << entry.path() << ": " << line;
                }
            }
        }
    }
}

}  // namespace test_modbus_layering_test
