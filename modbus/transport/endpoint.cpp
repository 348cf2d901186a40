#include "modbus/transport/endpoint.hpp"

#include <algorithm>
#include <charconv>
#include <vector>

namespace mbscope::modbus::transport {

std::string_view to_string(Scheme s) noexcept {
    switch (s) {
        case Scheme::Tcp:
            return "tcp";
        case Scheme::Udp:
            return "udp";
        case Scheme::RtuOverTcp:
            return "rtu-tcp";
        case Scheme::AsciiOverTcp:
            return "ascii-tcp";
        case Scheme::RtuSerial:
            return "rtu";
        case Scheme::AsciiSerial:
            return "ascii";
    }
    return "?";
}

Framing framing_of(Scheme s) noexcept {
    switch (s) {
        case Scheme::RtuOverTcp:
        case Scheme::RtuSerial:
            return Framing::Rtu;
        case Scheme::AsciiOverTcp:
        case Scheme::AsciiSerial:
            return Framing::Ascii;
        default:
            return Framing::Tcp;
    }
}

bool is_serial(Scheme s) noexcept {
    return s == Scheme::RtuSerial || s == Scheme::AsciiSerial;
}

LineState line_state(const Endpoint& e, std::uint8_t unit) noexcept {
    LineState line;
    line.unit = unit;
    if (const Framing f = framing_of(e.scheme); f != Framing::Tcp) line.framing = f;
    if (is_serial(e.scheme)) {
        line.baud = e.line.baud;
        line.parity = e.line.parity;
    }
    return line;
}

std::string Endpoint::text() const {
    if (is_serial(scheme)) {
        std::string out =
            std::string(to_string(scheme)) + ":" + device + "?baud=" + std::to_string(line.baud) +
            "&parity=" + std::string(1, "NEO"[static_cast<int>(line.parity)]) +
            "&stop=" + std::to_string(line.stop_bits) + "&data=" + std::to_string(line.data_bits);
        return out;
    }
    const bool v6 = host.find(':') != std::string::npos;
    return std::string(to_string(scheme)) + "://" + (v6 ? "[" + host + "]" : host) + ":" +
           std::to_string(port);
}

namespace {

template <class T>
bool parse_number(std::string_view s, T& out) {
    if (s.empty()) return false;
    auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
    return ec == std::errc{} && p == s.data() + s.size();
}

Result<Endpoint, std::string> parse_network(Scheme scheme, std::string_view rest, std::string_view uri) {
    Endpoint ep;
    ep.scheme = scheme;
    std::string_view host, port;
    if (!rest.empty() && rest.front() == '[') {  // [::1]:502
        const auto close = rest.find(']');
        if (close == std::string_view::npos) return std::string("unterminated '[' in ") + std::string(uri);
        host = rest.substr(1, close - 1);
        rest.remove_prefix(close + 1);
        if (!rest.empty() && rest.front() != ':')
            return std::string("expected ':PORT' after ']' in ") + std::string(uri);
        port = rest.empty() ? std::string_view{} : rest.substr(1);
    } else {
        const auto colon = rest.find(':');
        host = rest.substr(0, colon);
        if (colon != std::string_view::npos) port = rest.substr(colon + 1);
        // "::1:502" cannot say where the address ends: an IPv6 literal goes in brackets (RFC 3986 §3.2.2).
        if (port.find(':') != std::string_view::npos)
            return std::string("an IPv6 address needs brackets, as in tcp://[::1]:502, in ") +
                   std::string(uri);
    }
    if (host.empty()) return std::string("missing host in ") + std::string(uri);
    ep.host = std::string(host);
    const bool colon_given = rest.find(':') != std::string_view::npos;
    if (colon_given && port.empty()) return std::string("missing port after ':' in ") + std::string(uri);
    if (!port.empty()) {
        unsigned p = 0;
        if (!parse_number(port, p) || p > 65535)
            return std::string("bad port '") + std::string(port) + "' in " + std::string(uri);
        ep.port = static_cast<std::uint16_t>(p);
    }
    return ep;
}

Result<Endpoint, std::string> parse_serial(Scheme scheme, std::string_view rest, std::string_view uri) {
    Endpoint ep;
    ep.scheme = scheme;
    if (scheme == Scheme::AsciiSerial) {
        ep.line.data_bits = 7;  // SL §2.5.2: 7 data bits in ASCII mode
    }
    ep.line.parity = Parity::Even;  // SL §2.5.1/§2.5.2: even parity is the default
    const auto q = rest.find('?');
    ep.device = std::string(rest.substr(0, q));
    if (ep.device.empty()) return std::string("missing device in ") + std::string(uri);
    if (q == std::string_view::npos) return ep;
    std::string_view query = rest.substr(q + 1);
    std::vector<std::string_view> given;  // a key given twice is a mistake, not "the last one wins"
    while (!query.empty()) {
        const auto amp = query.find('&');
        const std::string_view kv = query.substr(0, amp);
        query = amp == std::string_view::npos ? std::string_view{} : query.substr(amp + 1);
        const auto eq = kv.find('=');
        if (eq == std::string_view::npos)
            return std::string("expected KEY=VALUE, got '") + std::string(kv) + "'";
        const std::string_view key = kv.substr(0, eq), value = kv.substr(eq + 1);
        if (std::find(given.begin(), given.end(), key) != given.end())
            return std::string(key) + " given twice in " + std::string(uri);
        given.push_back(key);
        const auto bad = [&] {
            return std::string("bad ") + std::string(key) + " '" + std::string(value) + "' in " +
                   std::string(uri);
        };
        if (key == "baud") {
            if (!parse_number(value, ep.line.baud) || ep.line.baud == 0) return bad();
        } else if (key == "parity") {
            const auto p = parse_parity(value);
            if (!p) return bad();
            ep.line.parity = *p;
        } else if (key == "stop") {
            unsigned s = 0;
            if (!parse_number(value, s) || (s != 1 && s != 2)) return bad();
            ep.line.stop_bits = static_cast<std::uint8_t>(s);
        } else if (key == "data") {
            unsigned d = 0;
            if (!parse_number(value, d) || d < 7 || d > 8) return bad();
            ep.line.data_bits = static_cast<std::uint8_t>(d);
        } else {
            return std::string("unknown option '") + std::string(key) + "' in " + std::string(uri) +
                   " (baud, parity, stop, data)";
        }
    }
    return ep;
}

}  // namespace

Result<Endpoint, std::string> parse_endpoint(std::string_view uri) {
    struct Prefix {
        std::string_view text;
        Scheme scheme;
    };
    static constexpr Prefix network[] = {{"tcp://", Scheme::Tcp},
                                         {"udp://", Scheme::Udp},
                                         {"rtu-tcp://", Scheme::RtuOverTcp},
                                         {"ascii-tcp://", Scheme::AsciiOverTcp}};
    for (const auto& p : network)
        if (uri.substr(0, p.text.size()) == p.text)
            return parse_network(p.scheme, uri.substr(p.text.size()), uri);
    static constexpr Prefix serial[] = {{"rtu:", Scheme::RtuSerial}, {"ascii:", Scheme::AsciiSerial}};
    for (const auto& p : serial)
        if (uri.substr(0, p.text.size()) == p.text)
            return parse_serial(p.scheme, uri.substr(p.text.size()), uri);
    return std::string("unknown endpoint '") + std::string(uri) +
           "' (tcp://, udp://, rtu-tcp://, ascii-tcp://HOST:PORT or rtu:, ascii:DEVICE?baud=..)";
}

}  // namespace mbscope::modbus::transport
