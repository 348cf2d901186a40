#include "analyzer/ip_reassembly.hpp"

#include <algorithm>

namespace mbscope::analyzer {

std::optional<IpDatagram> IpReassembler::add(const IpFragment& f, modbus::Timestamp time) {
    constexpr std::size_t largest = 65535;
    const std::size_t end = std::size_t{f.offset} + f.data.size();
    if (end > largest) {
        ++invalid_fragments_;
        return std::nullopt;
    }
    const Key key{f.v6, f.source, f.destination, f.id, f.protocol};
    auto it = partials_.find(key);
    if (it == partials_.end()) {
        if (partials_.size() >= max_datagrams) {
            while (!order_.empty()) {  // the oldest datagram still in progress makes room
                const auto [old, serial] = order_.front();
                order_.pop_front();
                if (auto o = partials_.find(old); o != partials_.end() && o->second.serial == serial) {
                    give_up(o);
                    break;
                }
            }
        }
        it = partials_.emplace(key, Partial{}).first;
        it->second.first = time;
        it->second.serial = ++next_serial_;
        order_.emplace_back(key, it->second.serial);
    }
    Partial& p = it->second;
    ++p.fragments;
    if (!f.more) p.total = p.total ? std::min(*p.total, end) : end;
    if (p.bytes.size() < end) {
        p.bytes.resize(end);
        p.have.resize(end);
    }
    for (std::size_t i = 0; i < f.data.size(); ++i) {
        const std::size_t at = f.offset + i;
        if (p.have[at]) continue;  // the first copy wins
        p.have[at] = true;
        p.bytes[at] = f.data[i];
        ++p.held;
    }
    if (!p.total || *p.total > p.bytes.size()) return std::nullopt;
    if (!std::all_of(p.have.begin(), p.have.begin() + static_cast<std::ptrdiff_t>(*p.total),
                     [](bool b) { return b; }))
        return std::nullopt;
    IpDatagram whole{f.source, f.destination, f.v6, f.protocol, std::move(p.bytes)};
    whole.bytes.resize(*p.total);  // bytes a fragment claimed past the last one's end are not the datagram's
    partials_.erase(it);
    return whole;
}

void IpReassembler::give_up(std::map<Key, Partial>::iterator it) {
    ++incomplete_datagrams_;
    incomplete_fragments_ += it->second.fragments;
    partials_.erase(it);
}

void IpReassembler::expire(modbus::Timestamp now, bool at_end) {
    while (!order_.empty()) {
        const auto [key, serial] = order_.front();
        auto it = partials_.find(key);
        if (it == partials_.end() || it->second.serial != serial) {  // completed meanwhile
            order_.pop_front();
            continue;
        }
        if (!at_end && now - it->second.first < timeout) break;
        order_.pop_front();
        give_up(it);
    }
}

}  // namespace mbscope::analyzer
