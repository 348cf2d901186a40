// Live capture (mbscope sniff's library): a Modbus/TCP exchange on the loopback interface through libpcap,
// and RTU bytes on two pseudo-terminals standing for the two taps of a serial line; each decoded as it
// comes, and the file written on the way decoded again. The exchanged frames are the MK manual's FC3
// example (000:356-370). Capturing on lo needs root or CAP_NET_RAW: without it the test is skipped with
// libpcap's reason, never passed.
#include <arpa/inet.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <pty.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <fcntl.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include "analyzer/live_capture.hpp"
#include "analyzer/pcapng_end.hpp"
#include "analyzer/serial_input.hpp"
#include "modbus/adu.hpp"
#include "modbus/storage/profile_store.hpp"
#include "test_packets.hpp"

namespace test_analyzer_sniff_test {

namespace an = mbscope::analyzer;
namespace mb = mbscope::modbus;
using mbscope::test::bytes;
using mbscope::test::Collect;

namespace {

const auto rtu_request = bytes({0x11, 0x03, 0x00, 0x60, 0x00, 0x03, 0x07, 0x45});
const auto rtu_response = bytes({0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64, 0xC8, 0xBA});
// The same PDUs behind an MBAP header, transaction id 7.
const auto tcp_request = bytes({0x00, 0x07, 0x00, 0x00, 0x00, 0x06, 0x11, 0x03, 0x00, 0x60, 0x00, 0x03});
const auto tcp_response =
    bytes({0x00, 0x07, 0x00, 0x00, 0x00, 0x09, 0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64});

void send_all(int fd, const std::vector<std::uint8_t>& b) {
    ASSERT_EQ(::send(fd, b.data(), b.size(), 0), static_cast<ssize_t>(b.size()));
}

void receive(int fd, std::size_t n) {
    std::vector<std::uint8_t> buf(n);
    std::size_t got = 0;
    while (got < n) {
        const ssize_t r = ::recv(fd, buf.data() + got, n - got, 0);
        ASSERT_GT(r, 0);
        got += static_cast<std::size_t>(r);
    }
}

std::unique_ptr<Collect> decode_file(const std::string& path, an::AnalyzerOptions options) {
    auto sink = std::make_unique<Collect>();
    an::Analyzer a(std::move(options), *sink);
    an::read_input(a, path, an::InputFormat::Pcap);
    a.finish();
    return sink;
}

// The file's first four bytes, as a little-endian number: a pcapng Section Header Block starts 0x0A0D0D0A,
// a classic pcap file 0xA1B2C3D4 (microseconds).
std::uint32_t magic(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    unsigned char b[4] = {};
    in.read(reinterpret_cast<char*>(b), 4);
    return b[0] | b[1] << 8 | b[2] << 16 | static_cast<std::uint32_t>(b[3]) << 24;
}
constexpr std::uint32_t pcapng_magic = 0x0A0D0D0A, pcap_magic = 0xA1B2C3D4;

// Runs `capture` into `a` while the FC3 request is written into the pty `master`, then stops it, or with
// `stop_after` false lets it end by itself. What run() returned.
bool sniff_request(an::LiveCapture& capture, an::Analyzer& a, int master, bool stop_after = true) {
    std::atomic<bool> stop{false};
    bool ran = false;
    std::thread sniffer([&] { ran = capture.run(a, stop); });
    const ssize_t written = ::write(master, rtu_request.data(), rtu_request.size());
    stop = stop_after;
    sniffer.join();
    a.finish();
    EXPECT_EQ(written, 8);
    return ran;
}

// A pseudo-terminal standing for a serial line: `master` is the line's far end, `path` the port a capture
// opens; closed when the test ends.
struct Pty {
    int master = -1, slave = -1;
    char path[64] = {};
    Pty() { EXPECT_EQ(::openpty(&master, &slave, path, nullptr, nullptr), 0); }
    ~Pty() {
        ::close(master);
        ::close(slave);
    }
    Pty(const Pty&) = delete;
    Pty& operator=(const Pty&) = delete;
};

// A live capture of the pseudo-terminal with `o`'s other options; null (the test failed) when it cannot
// be opened.
std::unique_ptr<an::LiveCapture> capture_of(const Pty& pty, an::SniffOptions o = {}) {
    o.serial = pty.path;
    std::string error;
    bool denied = false;
    auto capture = an::LiveCapture::open(o, error, denied);
    EXPECT_TRUE(capture) << error;
    return capture;
}

}  // namespace

TEST(Sniff, FilterNamesEveryPort) {
    an::SniffOptions o;
    o.tcp_ports = {502, 1502};
    o.udp_ports = {502};
    EXPECT_EQ(an::capture_filter(o),
              "tcp port 502 or tcp port 1502 or udp port 502 or (ip and ip[6:2] & 0x1fff != 0) or (ip6 and "
              "ip6[6] == 44)");
}

// A Modbus/TCP exchange on lo, decoded as it comes and written into `name`, whose format `expected_magic`
// names; the file decodes again into the same transaction at the same times.
void loopback_exchange(const std::string& name, std::uint32_t expected_magic) {
    // The server first, for its port: the capture filters on it.
    const int server = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(::bind(server, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    ASSERT_EQ(::listen(server, 1), 0);
    socklen_t len = sizeof addr;
    ::getsockname(server, reinterpret_cast<sockaddr*>(&addr), &len);
    const std::uint16_t port = ntohs(addr.sin_port);

    an::SniffOptions o;
    o.interface = "lo";
    o.tcp_ports = {port};
    o.udp_ports = {};
    o.write = ::testing::TempDir() + name;
    std::string error;
    bool denied = false;
    auto capture = an::LiveCapture::open(o, error, denied);
    if (!capture) {
        ::close(server);
        if (denied) GTEST_SKIP() << "no permission to capture on lo: " << error;
        FAIL() << error;
    }
    Collect sink;
    an::AnalyzerOptions options;
    options.tcp_ports = {port};
    an::Analyzer a(options, sink);
    std::atomic<bool> stop{false};
    bool ran = false;
    std::thread sniffer([&] { ran = capture->run(a, stop); });

    const int client = ::socket(AF_INET, SOCK_STREAM, 0);
    ASSERT_EQ(::connect(client, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    const int accepted = ::accept(server, nullptr, nullptr);
    send_all(client, tcp_request);
    receive(accepted, tcp_request.size());
    send_all(accepted, tcp_response);
    receive(client, tcp_response.size());
    ::close(client);
    ::close(accepted);
    ::close(server);
    // While the capture still runs, the file already holds the exchange: it is flushed as time passes, not
    // only at the end (a sniff killed, or stopped by `| head`, left a network capture file without packets).
    bool in_file = false;
    for (int i = 0; i < 100 && !in_file; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        const auto so_far = decode_file(o.write, options);
        in_file = so_far->transactions.size() == 1 && so_far->transactions[0].response.has_value();
    }
    EXPECT_TRUE(in_file) << o.write;
    stop = true;
    sniffer.join();
    a.finish();

    EXPECT_TRUE(ran);
    EXPECT_GE(capture->captured(), 4u);  // handshake, request, response at least
    ASSERT_EQ(sink.transactions.size(), 1u);
    EXPECT_TRUE(sink.transactions[0].response.has_value());
    EXPECT_EQ(sink.transactions[0].request.frame.unit_id(), 0x11);
    EXPECT_TRUE(sink.findings.empty());
    capture.reset();  // closes the file

    EXPECT_EQ(magic(o.write), expected_magic) << o.write;
    const auto again = decode_file(o.write, options);
    ASSERT_EQ(again->transactions.size(), 1u);
    ASSERT_TRUE(again->transactions[0].response.has_value());
    EXPECT_EQ(again->transactions[0].request.time, sink.transactions[0].request.time);
    EXPECT_EQ(again->transactions[0].response->time, sink.transactions[0].response->time);
}

TEST(Sniff, LoopbackModbusTcpExchangeIsDecodedAndWrittenAsClassicPcap) {
    loopback_exchange("sniff_lo.pcap", pcap_magic);
}

TEST(Sniff, LoopbackModbusTcpExchangeIsDecodedAndWrittenAsPcapng) {
    loopback_exchange("sniff_lo.pcapng", pcapng_magic);
}

TEST(Sniff, TwoSerialTapsGiveDirectionsAndAUserZeroFile) {
    int master[2], slave[2];
    char path[2][64];
    for (int i = 0; i < 2; ++i) {
        ASSERT_EQ(::openpty(&master[i], &slave[i], path[i], nullptr, nullptr), 0);
    }
    an::SniffOptions o;
    o.serial = path[0];
    o.serial2 = path[1];
    o.write = ::testing::TempDir() + "sniff_serial.pcapng";
    std::string error;
    bool denied = false;
    auto capture = an::LiveCapture::open(o, error, denied);
    ASSERT_TRUE(capture) << error;
    Collect sink;
    an::Analyzer a({}, sink);
    std::atomic<bool> stop{false};
    std::thread sniffer([&] { capture->run(a, stop); });
    ASSERT_EQ(::write(master[0], rtu_request.data(), rtu_request.size()), 8);
    ASSERT_EQ(::write(master[1], rtu_response.data(), rtu_response.size()), 11);
    stop = true;
    sniffer.join();
    a.finish();
    for (int i = 0; i < 2; ++i) {
        ::close(master[i]);
        ::close(slave[i]);
    }

    ASSERT_EQ(sink.transactions.size(), 1u);
    EXPECT_TRUE(sink.transactions[0].response.has_value());
    EXPECT_EQ(sink.transactions[0].request.direction, mb::Direction::Request);
    EXPECT_TRUE(sink.findings.empty());
    EXPECT_TRUE(capture->direction_header());
    capture.reset();

    // Two taps: each USER0 record leads with its direction byte, and decodes into the same directions and
    // times (pcapng keeps the nanoseconds the reads were stamped with).
    EXPECT_EQ(magic(o.write), pcapng_magic);
    an::AnalyzerOptions user0;
    user0.user_dlt = mb::Framing::Rtu;
    user0.user_dlt_direction = true;
    const auto again = decode_file(o.write, user0);
    ASSERT_EQ(again->transactions.size(), 1u);
    ASSERT_TRUE(again->transactions[0].response.has_value());
    EXPECT_EQ(again->transactions[0].request.direction, mb::Direction::Request);
    EXPECT_EQ(again->transactions[0].response->direction, mb::Direction::Response);
    EXPECT_EQ(again->transactions[0].request.time, sink.transactions[0].request.time);
    EXPECT_EQ(again->transactions[0].response->time, sink.transactions[0].response->time);
    EXPECT_TRUE(again->findings.empty());
}

// A device that never answers, on a line that then stays quiet: its request was framed only when more bytes
// came or the capture ended, and then reported "unanswered when the capture ended" (a note, exit code 0)
// however long the capture had run past its timeout. Time passes while the capture runs: the request is
// framed and times out before the capture ends.
TEST(Sniff, ASilentDeviceTimesOutWhileTheCaptureRuns) {
    Pty pty;
    an::SniffOptions o;
    o.duration = std::chrono::milliseconds(2500);  // the request's 1 s timeout runs out well within it
    auto capture = capture_of(pty, o);
    ASSERT_TRUE(capture);
    Collect sink;
    an::AnalyzerOptions options;
    options.serial_framing = mb::Framing::Rtu;
    an::Analyzer a(options, sink);
    std::atomic<bool> stop{false};
    bool ran = false;
    std::thread sniffer([&] { ran = capture->run(a, stop); });
    EXPECT_EQ(::write(pty.master, rtu_request.data(), rtu_request.size()), 8);
    sniffer.join();
    EXPECT_TRUE(ran);
    // Before finish(): what the capture said while it ran.
    EXPECT_EQ(sink.frames.size(), 1u);
    EXPECT_EQ(sink.count(mb::FindingCode::PairNoResponse), 1);
    ASSERT_EQ(sink.transactions.size(), 1u);
    EXPECT_TRUE(sink.transactions[0].timed_out);
    a.finish();
    EXPECT_EQ(sink.count(mb::FindingCode::PairNoResponseAtEnd), 0);
    EXPECT_EQ(a.summary().errors, 1u);
}

// An MK device told BAUD := 3 (2400 baud, 000:501-503) acknowledges at the old speed and then talks at the
// new one. The analysis followed it, but the sniffer's port stayed at 9600 baud: every byte from then on was
// read garbled. The port now follows the line (a pseudo-terminal keeps the speed it is set to).
TEST(Sniff, TheSerialPortFollowsTheSpeedADeviceAcknowledged) {
    Pty pty;
    auto capture = capture_of(pty);
    ASSERT_TRUE(capture);
    mb::storage::ProfileStore store({std::string(MBSCOPE_SOURCE_DIR) + "/profiles"});
    auto profile = store.load("mmk-2030");
    ASSERT_TRUE(profile.has_value());
    an::AnalyzerOptions options;
    options.serial_framing = mb::Framing::Rtu;
    options.semantics = std::make_shared<an::Semantics>();
    options.semantics->add({}, std::make_shared<const mb::Profile>(std::move(profile.value())));
    Collect sink;
    an::Analyzer a(options, sink);
    const auto speed = [&] {
        termios t{};
        ::tcgetattr(pty.slave, &t);
        return ::cfgetispeed(&t);
    };
    EXPECT_EQ(speed(), B9600);
    std::atomic<bool> stop{false};
    std::thread sniffer([&] { capture->run(a, stop); });
    const auto baud_2400 = mb::encode_rtu(1, mb::encode_pdu(mb::make_write_single_register(9, 3)));
    EXPECT_EQ(::write(pty.master, baud_2400.data(), baud_2400.size()), 8);  // the master's request
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    EXPECT_EQ(::write(pty.master, baud_2400.data(), baud_2400.size()), 8);  // the device's echo
    for (int i = 0; i < 100 && speed() != B2400; ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    EXPECT_EQ(speed(), B2400);
    stop = true;
    sniffer.join();
    a.finish();
    EXPECT_EQ(sink.count(mb::FindingCode::ProfileLineSettingsChanged), 1);
    EXPECT_TRUE(a.summary().input_errors.empty());
}

// A line that never falls silent for the drain's 20 ms (a busy bus, a chattering device) kept a stopped
// capture reading it for as long as it talked: a stop must stop. The writer here talks every 5 ms for up to
// 20 s; the capture is stopped after 200 ms and must return while the line is still talking.
TEST(Sniff, AStopStopsOnALineThatNeverFallsSilent) {
    Pty pty;
    auto capture = capture_of(pty);
    ASSERT_TRUE(capture);
    Collect sink;
    an::Analyzer a({}, sink);
    std::atomic<bool> stop{false}, returned{false}, still_talking{false};
    std::thread talker([&] {
        const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(20);
        while (!returned && std::chrono::steady_clock::now() < end) {
            if (::write(pty.master, rtu_request.data(), rtu_request.size()) < 0) break;
            std::this_thread::sleep_for(std::chrono::milliseconds(5));
        }
        still_talking = std::chrono::steady_clock::now() < end;
    });
    std::thread sniffer([&] {
        capture->run(a, stop);
        returned = true;
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    stop = true;
    sniffer.join();
    talker.join();
    a.finish();
    EXPECT_TRUE(still_talking);
    EXPECT_GT(sink.frames.size(), 10u);
}

TEST(Sniff, PcapngIsChosenByTheNameInAnyCase) {
    EXPECT_TRUE(an::writes_pcapng("plant.pcapng"));
    EXPECT_TRUE(an::writes_pcapng("/tmp/PLANT.PcapNG"));
    EXPECT_FALSE(an::writes_pcapng("plant.pcap"));
    EXPECT_FALSE(an::writes_pcapng("/tmp/a.pcapng/plant"));
    EXPECT_FALSE(an::writes_pcapng("pcapng"));
}

// One tap into `name`: plain USER0 records, decoded again into the request.
void one_serial_tap(const std::string& name, std::uint32_t expected_magic) {
    an::SniffOptions o;
    o.write = ::testing::TempDir() + name;
    {
        Pty pty;
        auto capture = capture_of(pty, o);
        ASSERT_TRUE(capture);
        EXPECT_FALSE(capture->direction_header());
        Collect sink;
        an::Analyzer a({}, sink);
        EXPECT_TRUE(sniff_request(*capture, a, pty.master));
    }
    EXPECT_EQ(magic(o.write), expected_magic) << o.write;
    an::AnalyzerOptions user0;
    user0.user_dlt = mb::Framing::Rtu;
    const auto again = decode_file(o.write, user0);
    ASSERT_EQ(again->transactions.size(), 1u);
    EXPECT_EQ(again->transactions[0].request.frame.unit_id(), 0x11);
}

TEST(Sniff, OneSerialTapWritesPlainUserZeroRecordsAsPcapng) {
    one_serial_tap("sniff_one.PCAPNG", pcapng_magic);
}

TEST(Sniff, OneSerialTapWritesPlainUserZeroRecordsAsClassicPcap) {
    one_serial_tap("sniff_one.pcap", pcap_magic);
}

TEST(Sniff, UnwritableFileIsNamedWhenOpening) {
    int master = -1, slave = -1;
    char path[64];
    ASSERT_EQ(::openpty(&master, &slave, path, nullptr, nullptr), 0);
    for (const std::string name : {"sniff_dir.pcapng", "sniff_dir.pcap"}) {
        an::SniffOptions o;
        o.serial = path;
        o.write = ::testing::TempDir() + name;
        std::filesystem::create_directories(o.write);  // a directory where the file should go
        std::string error;
        bool denied = false;
        EXPECT_FALSE(an::LiveCapture::open(o, error, denied));
        EXPECT_EQ(error.rfind(o.write + ": ", 0), 0u) << error;
        EXPECT_EQ(error.find(o.write, 1), std::string::npos) << error;  // named once
    }
    ::close(master);
    ::close(slave);
}

TEST(Sniff, FullDiskEndsTheCaptureWithAnErrorNamingTheFile) {
    if (!std::filesystem::exists("/dev/full")) GTEST_SKIP() << "needs /dev/full";
    int master = -1, slave = -1;
    char path[64];
    ASSERT_EQ(::openpty(&master, &slave, path, nullptr, nullptr), 0);
    // Names that choose the format, on a device where every write fails for want of space.
    const std::string ng = ::testing::TempDir() + "sniff_full.pcapng",
                      classic = ::testing::TempDir() + "sniff_full.pcap";
    for (const auto& link : {ng, classic}) {
        std::filesystem::remove(link);
        std::filesystem::create_symlink("/dev/full", link);
    }
    const std::string no_space = std::strerror(ENOSPC);
    an::SniffOptions o;
    o.serial = path;
    std::string error;
    bool denied = false;
    // pcapng: the header is flushed when the file is opened, and fails there.
    o.write = ng;
    EXPECT_FALSE(an::LiveCapture::open(o, error, denied));
    EXPECT_EQ(error, ng + ": " + no_space);
    // Classic pcap: the first record flushed fails and ends the run.
    o.write = classic;
    o.duration = std::chrono::seconds(10);  // a bound, should the write not fail
    auto capture = an::LiveCapture::open(o, error, denied);
    ASSERT_TRUE(capture) << error;
    Collect sink;
    an::Analyzer a({}, sink);
    EXPECT_FALSE(sniff_request(*capture, a, master, false));  // ends by itself, on the failed write
    ::close(master);
    ::close(slave);
    ASSERT_EQ(a.summary().input_errors.size(), 1u);
    EXPECT_EQ(a.summary().input_errors[0], classic + ": " + no_space);
}

// Two UDP sockets on lo: a server bound to a port of its own, and a client. For captures of Modbus/UDP.
struct UdpPair {
    int server = ::socket(AF_INET, SOCK_DGRAM, 0), client = ::socket(AF_INET, SOCK_DGRAM, 0);
    sockaddr_in server_addr{}, client_addr{};
    std::uint16_t port = 0;
    UdpPair() {
        server_addr.sin_family = AF_INET;
        server_addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        EXPECT_EQ(::bind(server, reinterpret_cast<sockaddr*>(&server_addr), sizeof server_addr), 0);
        socklen_t len = sizeof server_addr;
        ::getsockname(server, reinterpret_cast<sockaddr*>(&server_addr), &len);
        port = ntohs(server_addr.sin_port);
        client_addr = server_addr;
        client_addr.sin_port = 0;
        EXPECT_EQ(::bind(client, reinterpret_cast<sockaddr*>(&client_addr), sizeof client_addr), 0);
        len = sizeof client_addr;
        ::getsockname(client, reinterpret_cast<sockaddr*>(&client_addr), &len);
    }
    ~UdpPair() {
        ::close(server);
        ::close(client);
    }
    UdpPair(const UdpPair&) = delete;
    UdpPair& operator=(const UdpPair&) = delete;
    void request(const std::vector<std::uint8_t>& b) const {
        EXPECT_EQ(::sendto(client, b.data(), b.size(), 0, reinterpret_cast<const sockaddr*>(&server_addr),
                           sizeof server_addr),
                  static_cast<ssize_t>(b.size()));
    }
    void reply(const std::vector<std::uint8_t>& b) const {
        EXPECT_EQ(::sendto(server, b.data(), b.size(), 0, reinterpret_cast<const sockaddr*>(&client_addr),
                           sizeof client_addr),
                  static_cast<ssize_t>(b.size()));
    }
};

// A capture of lo for the pair's port; null when capturing is not permitted (the caller skips).
std::unique_ptr<an::LiveCapture> capture_udp(const UdpPair& udp, an::SniffOptions o,
                                             std::string& denied_why) {
    o.interface = "lo";
    o.tcp_ports = {};
    o.udp_ports = {udp.port};
    std::string error;
    bool denied = false;
    auto capture = an::LiveCapture::open(o, error, denied);
    if (!capture && denied) denied_why = error;
    if (!capture && !denied) ADD_FAILURE() << error;
    return capture;
}

// Runs the capture until what was sent before has been read (a short moment), then stops it.
bool run_briefly(an::LiveCapture& capture, an::Analyzer& a) {
    std::atomic<bool> stop{false};
    bool ran = false;
    std::thread sniffer([&] { ran = capture.run(a, stop); });
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    stop = true;
    sniffer.join();
    a.finish();
    return ran;
}

// The kernel keeps what the capture has not read in a buffer, and drops what does not fit: the packets
// lost were never said (and their exchanges came out unanswered). A buffer of 1 MiB holds 16 packets of
// lo's 64 KiB frames; 200 datagrams sent before the capture reads anything overflow it.
TEST(Sniff, PacketsTheKernelDroppedAreInputErrors) {
    UdpPair udp;
    an::SniffOptions o;
    o.buffer_mib = 1;
    o.write = ::testing::TempDir() + "sniff_drops.pcapng";
    std::string denied;
    auto capture = capture_udp(udp, o, denied);
    if (!capture) {
        if (!denied.empty()) GTEST_SKIP() << "no permission to capture on lo: " << denied;
        return;
    }
    auto request = tcp_request;
    for (int i = 0; i < 200; ++i) {
        request[1] = static_cast<std::uint8_t>(i);
        udp.request(request);
    }
    Collect sink;
    an::AnalyzerOptions options;
    options.udp_ports = {udp.port};
    an::Analyzer a(options, sink);
    run_briefly(*capture, a);
    EXPECT_GT(capture->dropped(), 0u);
    // (Not captured + dropped = 200: on lo the kernel counts the drops of both copies of a packet, the
    // outgoing one libpcap would have passed over.)
    EXPECT_LT(capture->captured(), 200u);
    // The file keeps the count for a later decode (pcapng statistics, isb_osdrop).
    const auto dropped = capture->dropped();
    capture.reset();  // closes the file
    std::uint64_t in_file = 0;
    (void)an::pcapng_capture_end(o.write, mb::Timestamp(0), &in_file);
    EXPECT_EQ(in_file, dropped);
    ASSERT_EQ(a.summary().input_errors.size(), 1u);
    EXPECT_NE(a.summary().input_errors[0].find("lo: the kernel dropped " + std::to_string(dropped) +
                                               " packets between "),
              std::string::npos)
        << a.summary().input_errors[0];
}

// A sink that takes its time over the first frame, as a slow reader of sniff's output makes the capture
// fall behind: meanwhile packets wait in the kernel's buffer.
struct SlowFirstFrame : Collect {
    bool slept = false;
    void frame(const an::FrameRecord& f) override {
        if (!std::exchange(slept, true)) std::this_thread::sleep_for(std::chrono::milliseconds(250));
        Collect::frame(f);
    }
};

// A capture that fell behind passed time for the analyzer by the clock, past packets still waiting to be
// read: a request whose reply had come 10 ms after it timed out (100 ms), then the reply was "late", and
// the capture's clock went back. Busy, time passes only by the packets read.
TEST(Sniff, AReaderBehindDoesNotTimeOutRepliesWaitingToBeRead) {
    UdpPair udp;
    std::string denied;
    auto capture = capture_udp(udp, {}, denied);
    if (!capture) {
        if (!denied.empty()) GTEST_SKIP() << "no permission to capture on lo: " << denied;
        return;
    }
    udp.request(tcp_request);
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    udp.reply(tcp_response);
    std::this_thread::sleep_for(std::chrono::milliseconds(400));  // both wait in the buffer, unread
    SlowFirstFrame sink;
    an::AnalyzerOptions options;
    options.udp_ports = {udp.port};
    options.timeout = std::chrono::milliseconds(100);
    an::Analyzer a(options, sink);
    EXPECT_TRUE(run_briefly(*capture, a));
    ASSERT_EQ(sink.transactions.size(), 1u);
    EXPECT_TRUE(sink.transactions[0].response.has_value());
    EXPECT_FALSE(sink.transactions[0].timed_out);
    EXPECT_TRUE(sink.findings.empty());
    EXPECT_TRUE(a.summary().input_notes.empty());  // no clock going back
    EXPECT_TRUE(a.summary().input_errors.empty());
}

// Two taps, both holding a read when the capture looks: --count 1 read both.
TEST(Sniff, CountOneReadsOneWithBothTapsReady) {
    Pty taps[2];
    ASSERT_EQ(::write(taps[0].master, rtu_request.data(), rtu_request.size()), 8);
    ASSERT_EQ(::write(taps[1].master, rtu_response.data(), rtu_response.size()), 11);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    an::SniffOptions o;
    o.serial2 = taps[1].path;
    o.count = 1;
    o.duration = std::chrono::seconds(10);  // a bound, should the count not end it
    auto capture = capture_of(taps[0], o);
    ASSERT_TRUE(capture);
    Collect sink;
    an::Analyzer a({}, sink);
    std::atomic<bool> stop{false};
    EXPECT_TRUE(capture->run(a, stop));
    EXPECT_EQ(capture->captured(), 1u);
}

// One tap hangs up while the other holds bytes not read yet: the capture ended at the hang-up, and what
// the other port held was lost without a word (a reply already written when the request's tap went away).
TEST(Sniff, WhatTheOtherTapHoldsIsReadWhenOneHangsUp) {
    Pty request_tap, reply_tap;
    an::SniffOptions o;
    o.serial2 = reply_tap.path;
    o.duration = std::chrono::seconds(10);  // a bound, should the hang-up not end it
    auto capture = capture_of(request_tap, o);
    ASSERT_TRUE(capture);
    ASSERT_EQ(::write(reply_tap.master, rtu_response.data(), rtu_response.size()), 11);
    ::close(request_tap.master);  // the first port hangs up; the second holds the reply
    request_tap.master = ::open("/dev/null", O_RDONLY);  // for ~Pty to close
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    Collect sink;
    an::Analyzer a({}, sink);
    std::atomic<bool> stop{false};
    EXPECT_FALSE(capture->run(a, stop));
    a.finish();
    ASSERT_EQ(a.summary().input_errors.size(), 1u);
    EXPECT_NE(a.summary().input_errors[0].find("hung up"), std::string::npos) << a.summary().input_errors[0];
    EXPECT_EQ(capture->captured(), 1u);
    ASSERT_EQ(sink.frames.size(), 1u);
    EXPECT_EQ(sink.frames[0].direction, mb::Direction::Response);
}

}  // namespace test_analyzer_sniff_test
