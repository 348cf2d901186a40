#pragma once
// The slave's wire side: one endpoint (tcp://, udp://, rtu-tcp://, ascii-tcp://, rtu:, ascii: or a
// pseudo-terminal), one or more units behind it, and the planted faults that live on the wire. A single
// poll() loop serves every connection: a slow or hostile client costs the others nothing but its turn.
//
//   bytes ─▶ deframer (MBAP / RTU / ASCII) ─▶ unit routing ─▶ Device::handle ─▶ PDU faults ─▶ framing
//        ─▶ ADU faults ─▶ send queue (slow-reply and gap-inside-frame delays)
//
// Serial lines follow SL §2.5.1.1: a request ends at a silence of t3.5 (so the answer never starts before
// it), and a request holding a silence above t1.5 or a bad CRC/LRC is never answered. A device told other
// line settings (MK-CFG-01: PROT, BAUD, PARID written) takes them once its acknowledgement is out: the
// server's port and framing follow when every unit on the line holds them; until then it is off the line.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "modbus/result.hpp"
#include "modbus/transport/endpoint.hpp"
#include "slave/device.hpp"
#include "slave/faults.hpp"
#include "slave/state_file.hpp"

namespace mbscope::slave {

struct ServerOptions {
    std::chrono::milliseconds idle_timeout{60'000};  // a TCP client silent this long is disconnected
    std::chrono::milliseconds frame_timeout{
        5'000};  // a partial frame held this long: the client is half-open
    std::size_t max_clients = 1024;
    // RTU over TCP: bytes that the content cannot end as a frame are taken as complete after this silence
    // (a serial gateway's character timeout); what they hold is answered or dropped then.
    std::chrono::milliseconds stream_frame_silence{50};
    std::string state_file;   // saved after every acknowledged write when set
    OtherUnits state_others;  // the units state_file holds that this run does not serve: kept in it
    bool create_pty = false;  // serial schemes: create a pseudo-terminal instead of opening the device
    // Called between requests with the time, so the simulated process moves while the slave serves.
    std::function<void(std::chrono::steady_clock::time_point)> tick;
    std::chrono::milliseconds tick_interval{100};
    // Called with a sentence when a device takes other line settings (MK-CFG-01: PROT, BAUD, PARID
    // written) and the line follows it, or it leaves a line other units share.
    std::function<void(const std::string&)> on_line_change;
};

struct ServerStats {
    std::uint64_t requests = 0;
    std::uint64_t responses = 0;
    std::uint64_t bad_frames = 0;   // CRC/LRC errors, gaps over t1.5, MBAP garbage
    std::uint64_t connections = 0;  // accepted over the server's life
    std::uint64_t closed_idle = 0;  // closed by idle_timeout or frame_timeout
    std::uint64_t refused = 0;      // over max_clients
};

class Server {
  public:
    Server(modbus::transport::Endpoint endpoint, std::vector<Device*> units, FaultSet& faults,
           ServerOptions options);
    ~Server();
    Server(const Server&) = delete;
    Server& operator=(const Server&) = delete;

    // Binds or opens the endpoint. Errors name the endpoint and the cause.
    modbus::Result<void, std::string> open();
    // Where clients connect: "tcp://127.0.0.1:5020" (the real port when 0 was asked), or the pty's path.
    std::string address() const;
    std::uint16_t port() const noexcept;
    // The endpoint as served now: its scheme and line follow devices told other settings. Not while run()
    // is serving in another thread (it changes them).
    modbus::transport::Endpoint endpoint() const;
    // Serves until `stop` becomes true (checked at least every 100 ms). Errors: the endpoint failed.
    modbus::Result<void, std::string> run(const std::atomic<bool>& stop);
    const ServerStats& stats() const noexcept { return stats_; }

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    ServerStats stats_;
};

}  // namespace mbscope::slave
