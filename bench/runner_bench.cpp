// The conformance runner's cost per request against a bare libmodbus client loop, side by side in one run,
// both against the same reference slave (slave::Server on 127.0.0.1 in a thread, profile mmk-2030) and the
// same request (FC3, 10 registers from address 0).
//
//  - libmodbus: modbus_read_registers() in a loop (what a plain integration test would do);
//  - transport: modbus/transport's Client::transact (framing, response by content, timing kept);
//  - session:   conformance::Session::request, the path every rule takes (pacing check, evidence kept,
//               response times recorded), evidence cleared every 1000 requests as a rule's end does.
// The bound: the session within 1.5x of libmodbus.
#include <benchmark/benchmark.h>
#include <modbus.h>

#include <atomic>
#include <filesystem>
#include <memory>
#include <thread>

#include "conformance/session.hpp"
#include "modbus/pdu.hpp"
#include "modbus/storage/profile_store.hpp"
#include "modbus/transport/client.hpp"
#include "slave/server.hpp"

namespace {

namespace mb = mbscope::modbus;
namespace tp = mbscope::modbus::transport;

// One slave for the whole run.
struct Bench {
    mb::Profile profile;
    mbscope::slave::FaultSet faults;
    std::unique_ptr<mbscope::slave::Device> device;
    std::unique_ptr<mbscope::slave::Server> server;
    std::atomic<bool> stop{false};
    std::thread thread;

    Bench() {
        mb::storage::ProfileStore store({MBSCOPE_SOURCE_PROFILES});
        profile = store.load("mmk-2030").value();
        device = std::make_unique<mbscope::slave::Device>(profile, 1, &faults);
        server = std::make_unique<mbscope::slave::Server>(*tp::parse_endpoint("tcp://127.0.0.1:0"),
                                                          std::vector<mbscope::slave::Device*>{device.get()},
                                                          faults, mbscope::slave::ServerOptions{});
        if (!server->open()) std::abort();
        thread = std::thread([this] { (void)server->run(stop); });
    }
    ~Bench() {
        stop = true;
        thread.join();
    }
    std::uint16_t port() const { return server->port(); }
};

Bench& bench() {
    static Bench b;
    return b;
}

void BM_LibmodbusReadRegisters(benchmark::State& state) {
    modbus_t* ctx = modbus_new_tcp("127.0.0.1", bench().port());
    if (!ctx || modbus_connect(ctx) != 0) {
        state.SkipWithError("libmodbus cannot connect");
        return;
    }
    modbus_set_slave(ctx, 1);
    std::uint16_t regs[10];
    for (auto _ : state)
        if (modbus_read_registers(ctx, 0, 10, regs) != 10) state.SkipWithError("read failed");
    state.SetItemsProcessed(state.iterations());
    modbus_close(ctx);
    modbus_free(ctx);
}

void BM_TransportClientTransact(benchmark::State& state) {
    auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(bench().port())));
    if (!client) {
        state.SkipWithError("cannot connect");
        return;
    }
    const auto pdu = mb::encode_pdu(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 0, 10));
    for (auto _ : state) {
        auto ex = client->transact(1, pdu, std::chrono::milliseconds(1000));
        if (!ex.response) state.SkipWithError("no reply");
        benchmark::DoNotOptimize(ex);
    }
    state.SetItemsProcessed(state.iterations());
}

void BM_ConformanceSessionRequest(benchmark::State& state) {
    auto client = tp::Client::open(*tp::parse_endpoint("tcp://127.0.0.1:" + std::to_string(bench().port())));
    if (!client) {
        state.SkipWithError("cannot connect");
        return;
    }
    mbscope::conformance::Session session(*client, {}, &bench().profile);
    const auto pdu = mb::encode_pdu(mb::make_read_request(mb::FunctionCode::ReadHoldingRegisters, 0, 10));
    std::size_t n = 0;
    for (auto _ : state) {
        auto ex = session.request(pdu, "read");
        if (!ex.response) state.SkipWithError("no reply");
        if (++n % 1000 == 0) benchmark::DoNotOptimize(session.take_evidence());
    }
    state.SetItemsProcessed(state.iterations());
}

BENCHMARK(BM_LibmodbusReadRegisters)->UseRealTime();
BENCHMARK(BM_TransportClientTransact)->UseRealTime();
BENCHMARK(BM_ConformanceSessionRequest)->UseRealTime();
// Again in reverse order, so a drift of the machine during the run shows as a disagreement.
BENCHMARK(BM_ConformanceSessionRequest)->Name("BM_ConformanceSessionRequest/again")->UseRealTime();
BENCHMARK(BM_TransportClientTransact)->Name("BM_TransportClientTransact/again")->UseRealTime();
BENCHMARK(BM_LibmodbusReadRegisters)->Name("BM_LibmodbusReadRegisters/again")->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
