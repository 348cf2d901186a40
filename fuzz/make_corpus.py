#!/usr/bin/python3
"""Builds the seed corpora in corpus/<target>/ from material nobody chose for the fuzzer: the manuals' worked
example frames (captures/manual-examples.txt), the bundled captures and serial logs, and requests derived from
every bundled profile's map (first and last valid address of each table, the manual's quantity limits, a value
inside each writable point's range), and the files the programs themselves write: a state file of
`mbscope slave --state` after writes from a client, reproducers that `mbscope fuzz` saved against the
reference slave with planted faults. Each seed is laid out the way its target reads its input through
FuzzedDataProvider (control values from the end, data from the front), so the first run already reaches deep.

    fuzz/make_corpus.py --mbscope build/release/cli/mbscope            # write the seeds
    fuzz/make_corpus.py --mbscope ... --merge build/fuzz/fuzz          # then minimise: libFuzzer -merge=1

Files are named by the SHA-1 of their content, so running it twice changes nothing.
"""
import argparse
import hashlib
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# Every program this script runs finds the bundled profiles of this tree.
ENV = dict(os.environ, MBSCOPE_PROFILE_PATH=os.path.join(ROOT, "profiles"))
TARGETS = ["pdu", "rtu_deframer", "ascii_deframer", "tcp_stream", "capture", "serial_log", "profile", "slave",
           "slave_request", "libmodbus_diff", "slave_state", "reproducer", "frame_text", "reply", "check"]


class Provider:
    """The inverse of LLVM's FuzzedDataProvider: integers are taken from the end of the input (most significant
    byte first), byte runs from the front."""

    def __init__(self):
        self.front = bytearray()
        self.back = bytearray()  # in consumption order

    def integral(self, lo, hi, value):
        span = hi - lo
        count = 0
        while count < 8 and (span >> (8 * count)) > 0:
            count += 1
        v = value - lo
        self.back += bytes((v >> (8 * (count - 1 - i))) & 0xFF for i in range(count))

    def uint8(self, value):
        self.back.append(value & 0xFF)

    def boolean(self, value):
        self.uint8(1 if value else 0)

    def data(self, payload):
        self.front += payload

    def bytes(self):
        return bytes(self.front) + bytes(reversed(self.back))


def crc16(data):
    crc = 0xFFFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return bytes([crc & 0xFF, crc >> 8])


def rtu(unit, pdu):
    adu = bytes([unit]) + pdu
    return adu + crc16(adu)


def ascii_frame(unit, pdu):
    body = bytes([unit]) + pdu
    lrc = (-sum(body)) & 0xFF
    return b":" + (body + bytes([lrc])).hex().upper().encode() + b"\r\n"


def tcp(tid, unit, pdu):
    return tid.to_bytes(2, "big") + b"\x00\x00" + (len(pdu) + 1).to_bytes(2, "big") + bytes([unit]) + pdu


def manual_examples():
    """(framing, bytes) of every example frame in captures/manual-examples.txt."""
    out = []
    with open(os.path.join(ROOT, "captures", "manual-examples.txt")) as f:
        for line in f:
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            framing, rest = line.split(None, 1)
            if framing == "ascii":
                out.append((framing, rest.strip().encode() + b"\r\n"))
            else:
                out.append((framing, bytes.fromhex(rest)))
    return out


def pdu_of(framing, frame):
    if framing == "rtu":
        return frame[1:-2]
    if framing == "tcp":
        return frame[7:]
    body = bytes.fromhex(frame[1:-2].decode())
    return body[1:-1]


def profiles(mbscope):
    listed = json.loads(subprocess.check_output([mbscope, "profile", "list", "--json"], env=ENV))
    out = []
    for entry in listed:
        shown = json.loads(subprocess.check_output([mbscope, "profile", "show", entry["id"], "--json"], env=ENV))
        out.append(shown)
    return out


def requests_for(profile):
    """PDUs that exercise a profile's map: valid reads at both ends of each table, the manual's quantity limit
    and one past it, writes inside a writable point's range, FC8 echo and listen-only, and an unknown code."""
    fns = profile["functions"]
    limits = fns.get("max_quantity", {})
    pdus = []
    tables = {"coils": (1, 5, 15), "discrete_inputs": (2, None, None), "input_registers": (4, None, None),
              "holding_registers": (3, 6, 16)}
    for name, (read_fc, single_fc, multi_fc) in tables.items():
        points = profile["tables"].get(name, [])
        if isinstance(points, dict):  # {"same_as": TABLE}: the other table's map
            points = profile["tables"].get(points.get("same_as"), [])
        if not isinstance(points, list) or not points:
            # The generic profile has no map: every address exists.
            points = [{"address": 0, "access": "rw"}, {"address": 65535, "access": "rw"}] if profile.get(
                "id") == "modbus" else []
        if not points:
            continue
        first, last = points[0]["address"], points[-1]["address"]
        limit = int(limits.get(str(read_fc), 125 if read_fc > 2 else 2000))
        for start, quantity in ((first, 1), (last, 1), (first, min(limit, 125)), (first, limit + 1)):
            pdus.append(bytes([read_fc]) + start.to_bytes(2, "big") + quantity.to_bytes(2, "big"))
        writable = [p for p in points if p.get("access") in ("rw", "w")]
        for p in writable[:2]:
            value = p.get("range", {}).get("min", 0) & 0xFFFF
            if single_fc == 5:
                pdus.append(bytes([5]) + p["address"].to_bytes(2, "big") + b"\xff\x00")
                pdus.append(bytes([15]) + p["address"].to_bytes(2, "big") + b"\x00\x01\x01\x01")
            elif single_fc == 6:
                pdus.append(bytes([6]) + p["address"].to_bytes(2, "big") + value.to_bytes(2, "big"))
                pdus.append(bytes([16]) + p["address"].to_bytes(2, "big") + b"\x00\x01\x02" +
                            value.to_bytes(2, "big"))
            pdus.append(bytes([read_fc]) + p["address"].to_bytes(2, "big") + b"\x00\x01")  # read it back
    pdus += [b"\x08\x00\x00\x12\x34", b"\x08\x00\x04\x00\x00", b"\x03\x00\x00\x00\x01", b"\x08\x00\x01\x00\x00",
             b"\x41", b"\x2b\x0e\x01\x00", b"\x17\x00\x00\x00\x01\x00\x00\x00\x01\x02\x00\x00"]
    return pdus


class Slave:
    """`mbscope slave` on a loopback port for the duration of a `with` block; .address is where it listens."""

    def __init__(self, mbscope, *args):
        self.process = subprocess.Popen([mbscope, "slave", "-q"] + list(args), stdout=subprocess.PIPE, env=ENV)
        self.address = self.process.stdout.readline().decode().strip()

    def __enter__(self):
        return self

    def __exit__(self, *_):
        self.process.terminate()
        self.process.wait()


def state_files(mbscope):
    """State files `mbscope slave --state` writes for the four devices the slave_state target serves (units 1-4),
    after writes a client sends: the first write alone, then all of them."""
    writes = [(1, "06 00 54 FC 19"), (1, "05 00 01 FF 00"), (2, "10 00 94 00 02 04 00 00 40 E0"),
              (3, "06 00 02 00 07"), (4, "0F 00 10 00 0A 02 FF 03"), (4, "10 FF FE 00 02 04 12 34 56 78")]
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "state.json")
        with Slave(mbscope, "--listen", "tcp://127.0.0.1:0", "--state", path, "--unit", "1=mmk-2030", "--unit",
                   "2=walchem-w600", "--unit", "3=cth2265i", "--unit", "4=modbus") as slave:
            host, port = slave.address[len("tcp://"):].rsplit(":", 1)
            with socket.create_connection((host, int(port)), timeout=5) as s:
                for tid, (unit, pdu) in enumerate(writes):
                    s.sendall(tcp(tid, unit, bytes.fromhex(pdu)))
                    s.recv(300)
                    if tid in (0, len(writes) - 1):
                        out.append(open(path, "rb").read())
    return out


def reproducers(mbscope):
    """Reproducers `mbscope fuzz` saves against the reference slave with a planted fault, one per transport."""
    out = []
    for endpoint, fault in (("tcp", "wrong-tid"), ("rtu-tcp", "bad-crc"), ("ascii-tcp", "bad-lrc")):
        with tempfile.TemporaryDirectory() as tmp, Slave(mbscope, "--listen", endpoint + "://127.0.0.1:0",
                                                          "--fault", fault) as slave:
            subprocess.run([mbscope, "fuzz", "--target", slave.address, "--profile", "modbus", "--requests", "20",
                            "--seed", "1", "--artifacts", tmp], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                           env=ENV, timeout=120)
            out += [open(os.path.join(tmp, name), "rb").read() for name in sorted(os.listdir(tmp))[:2]]
    return out


def pcapng_of(pcap, snaplens=(65535, 262144), raw_ip=False):
    """A classic little-endian pcap rewritten as pcapng, its packets spread over two interfaces of the same link
    type and different snapshot lengths, as mergecap writes a merge of captures taken with different limits
    (libpcap 1.10 alone refuses such a file; analyzer/pcapng_interfaces.hpp levels them). With raw_ip, an
    Ethernet capture's IPv4 packets without their Ethernet header on two raw-IP interfaces (LINKTYPE_RAW), as
    from two tun interfaces, which libpcap 1.10 alone refuses too."""
    import struct
    magic, = struct.unpack_from("<I", pcap)
    nano = magic == 0xA1B23C4D
    linktype, = struct.unpack_from("<I", pcap, 20)
    if raw_ip:
        assert linktype == 1, "raw_ip takes an Ethernet capture"
        linktype = 101

    def block(kind, body):
        body += b"\0" * (-len(body) % 4)
        return struct.pack("<II", kind, 12 + len(body)) + body + struct.pack("<I", 12 + len(body))

    out = block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1))
    for snaplen in snaplens:  # if_tsresol 9: nanoseconds
        out += block(1, struct.pack("<HHI", linktype, 0, snaplen) + struct.pack("<HHB3x", 9, 1, 9) + b"\0" * 4)
    offset, n = 24, 0
    while offset + 16 <= len(pcap):
        sec, frac, caplen, length = struct.unpack_from("<IIII", pcap, offset)
        data = pcap[offset + 16:offset + 16 + caplen]
        offset += 16 + caplen
        if raw_ip:
            if data[12:14] != b"\x08\x00":
                continue
            data, caplen, length = data[14:], caplen - 14, length - 14
        ns = sec * 1_000_000_000 + (frac if nano else frac * 1000)
        out += block(6, struct.pack("<IIIII", n % 2, ns >> 32, ns & 0xFFFFFFFF, caplen, length) + data)
        n += 1
    return out


def tunnelled_of(pcap):
    """An Ethernet classic pcap whose IPv4 packets travel, in turn, in the tunnels the analyzer decodes: an MPLS
    label, GRE with the frame inside (transparent Ethernet bridging), ERSPAN type II, VXLAN, GENEVE and a PPPoE
    session."""
    import struct
    outer_mac = bytes.fromhex("0011223344550066778899aa")

    def outer_ip(protocol, payload):
        return struct.pack(">BBHHHBBH4s4s", 0x45, 0, 20 + len(payload), 1, 0, 64, protocol, 0,
                           bytes([192, 168, 1, 1]), bytes([192, 168, 1, 2])) + payload

    def wrap(n, frame):
        if frame[12:14] != b"\x08\x00":
            return frame
        kind = n % 6
        if kind == 0:
            return frame[:12] + b"\x88\x47" + struct.pack(">I", (16 << 12) | 0x100 | 64) + frame[14:]
        if kind == 5:
            return frame[:12] + b"\x88\x64" + struct.pack(">BBHHH", 0x11, 0, 0x1234, len(frame) - 12, 0x21) + frame[14:]
        if kind == 1:
            tunnel = outer_ip(47, b"\x00\x00\x65\x58" + frame)
        elif kind == 2:
            tunnel = outer_ip(47, b"\x10\x00\x88\xbe" + struct.pack(">I", n) + b"\x10\x00\x00\x01\x00\x00\x00\x00"
                              + frame)
        else:
            port, flags = (4789, b"\x08\x00\x00\x00") if kind == 3 else (6081, b"\x00\x00\x65\x58")
            vxlan = flags + b"\x00\x00\x2a\x00" + frame
            tunnel = outer_ip(17, struct.pack(">HHHH", 49152, port, 8 + len(vxlan), 0) + vxlan)
        return outer_mac + b"\x08\x00" + tunnel

    out, offset, n = bytearray(pcap[:24]), 24, 0
    while offset + 16 <= len(pcap):
        sec, frac, caplen, length = struct.unpack_from("<IIII", pcap, offset)
        frame = wrap(n, pcap[offset + 16:offset + 16 + caplen])
        out += struct.pack("<IIII", sec, frac, len(frame), length - caplen + len(frame)) + frame
        offset += 16 + caplen
        n += 1
    return bytes(out)


def max_len(target):
    """The target's max_len from fuzz/<target>.options, or None: libFuzzer reads no more of a seed than that,
    so a longer seed is only its first max_len bytes, and is written as such."""
    try:
        with open(os.path.join(ROOT, "fuzz", target + ".options")) as f:
            for line in f:
                key, _, value = line.partition("=")
                if key.strip() == "max_len":
                    return int(value)
    except FileNotFoundError:
        pass
    return None


def write(target, payload, out_dir):
    directory = os.path.join(out_dir, target)
    os.makedirs(directory, exist_ok=True)
    payload = payload[:max_len(target)]
    with open(os.path.join(directory, hashlib.sha1(payload).hexdigest()), "wb") as f:
        f.write(payload)


def build(mbscope, out_dir):
    examples = manual_examples()
    rtu_frames = [b for f, b in examples if f == "rtu"]
    ascii_frames = [b for f, b in examples if f == "ascii"]
    captures = [os.path.join(ROOT, "captures", n) for n in sorted(os.listdir(os.path.join(ROOT, "captures")))]
    pcaps = [open(p, "rb").read() for p in captures if p.endswith((".pcap", ".pcapng"))]
    classic = [p for p in pcaps if p[:4] in (b"\xd4\xc3\xb2\xa1", b"\x4d\x3c\xb2\xa1")]
    pcaps += [pcapng_of(p) for p in classic]
    pcaps += [pcapng_of(p, raw_ip=True) for p in classic if p[20:24] == b"\x01\x00\x00\x00"]
    pcaps += [tunnelled_of(p) for p in classic if p[20:24] == b"\x01\x00\x00\x00"]
    logs = [open(p, "rb").read() for p in captures if p.endswith(".log")]
    all_profiles = profiles(mbscope)

    # pdu: direction flag in the first byte, then the PDU.
    for framing, frame in examples:
        pdu = pdu_of(framing, frame)
        for direction in (0, 1):
            write("pdu", bytes([direction]) + pdu, out_dir)

    # rtu_deframer / ascii_deframer: the frames as one stream, chunked and timed by the trailing bytes.
    for timed in (False, True):
        p = Provider()
        p.boolean(timed)
        p.integral(0, 3, 1)  # 9600 baud
        for frame in rtu_frames:
            p.integral(1, 64, len(frame))
            p.integral(0, 20000, 5000 if timed else 0)
            p.data(frame)
        write("rtu_deframer", p.bytes(), out_dir)
        p = Provider()
        p.boolean(timed)
        for frame in ascii_frames + [ascii_frame(0x11, pdu_of("rtu", f)) for f in rtu_frames]:
            p.integral(1, 64, min(len(frame), 64))
            p.integral(0, 1500, 10)
            p.data(frame[:64])
        write("ascii_deframer", p.bytes(), out_dir)

    # tcp_stream and libmodbus_diff: the examples' PDUs over MBAP, and the profile-derived requests.
    mbap = [tcp(i + 1, 0x11, pdu_of(f, b)) for i, (f, b) in enumerate(examples)]
    stream = b"".join(mbap)[:2048]
    p = Provider()
    p.integral(0, 0xFFFFFFFF, 0xFFFFFF00)  # sequence numbers that wrap
    p.integral(0, 2048, len(stream))
    p.data(stream)
    p.integral(64, 4096, 4096)
    offset = 0
    for adu in mbap:  # in order, then the first ADU again (a retransmission)
        if offset + len(adu) > len(stream):
            break
        p.integral(0, len(stream) - 1, offset)
        p.integral(1, min(300, len(stream) - offset), len(adu))
        p.uint8(0)
        offset += len(adu)
    write("tcp_stream", p.bytes(), out_dir)
    for adu in mbap:
        write("libmodbus_diff", adu, out_dir)
    generic = next(pr for pr in all_profiles if pr["id"] == "modbus")
    for i, pdu in enumerate(requests_for(generic)):
        write("libmodbus_diff", tcp(0x100 + i, 1, pdu), out_dir)

    # capture: the pcap, then one byte of analyzer options (0: defaults; 0x20: with a profile).
    for pcap in pcaps:
        for flags in (0x00, 0x24):
            p = Provider()
            p.uint8(flags)
            if flags & 0x20:
                p.integral(0, len(all_profiles) - 1, 0)
            p.data(pcap)
            write("capture", p.bytes(), out_dir)

    # serial_log: format "auto", 9600 baud, no parity, no profile, framing told by the bytes, then the log;
    # the text format from the examples. Then an MK device told PROT := 0 (ASCII) in RTU and read in ASCII
    # (MK-CFG-01), described by its profile: the line is deframed again from the acknowledgement on.
    text = "".join("%.3f %s %s\n" % (1 + i * 0.05, ">" if i % 2 == 0 else "<", frame.hex(" ").upper())
                   for i, frame in enumerate(rtu_frames)).encode()
    for log in logs + [text, b"".join(rtu_frames), b"".join(ascii_frames)]:
        p = Provider()
        p.integral(0, 5, 0)
        p.integral(0, 3, 1)
        p.boolean(False)
        p.boolean(False)
        p.integral(0, 2, 0)
        p.data(log)
        write("serial_log", p.bytes(), out_dir)
    prot = [rtu(1, bytes.fromhex("0300080001")), rtu(1, bytes.fromhex("03020001")),
            rtu(1, bytes.fromhex("0600080000")), rtu(1, bytes.fromhex("0600080000")),
            ascii_frame(1, bytes.fromhex("0300080001")), ascii_frame(1, bytes.fromhex("03020000"))]
    ids = [pr["id"] for pr in all_profiles]
    for log in (b"".join(prot), "".join("%.3f %s %s\n" % (1 + i * 0.05, ">" if i % 2 == 0 else "<",
                                                          frame.hex(" ").upper())
                                         for i, frame in enumerate(prot)).encode()):
        p = Provider()
        p.integral(0, 5, 0)
        p.integral(0, 3, 1)
        p.boolean(False)
        p.boolean(True)
        p.integral(0, len(all_profiles) - 1, ids.index("mmk-2030"))
        p.integral(0, 2, 0)
        p.data(log)
        write("serial_log", p.bytes(), out_dir)

    # profile: the smaller bundled documents as they are.
    for name in ("modbus.json", "cth2265i.json", os.path.join("mk", "3.08-mmk-2030.json")):
        write("profile", open(os.path.join(ROOT, "profiles", name), "rb").read(), out_dir)

    # slave: per profile and framing, its derived requests framed correctly, each followed by a copy with a
    # broken checksum (raw), to one unit.
    framings = ["rtu", "ascii", "tcp"]
    for index, pr in enumerate(all_profiles):
        unit = max(1, min(pr.get("line", {}).get("unit_min", 1), 247))
        for framing_index, framing in enumerate(framings):
            if framing != "tcp" and index % 4 != 0:
                continue  # serial framings on a quarter of the profiles keep the corpus small
            p = Provider()
            p.integral(0, len(all_profiles) - 1, index)
            p.integral(0, len(all_profiles) - 1, index)
            p.integral(0, 2, framing_index)
            p.boolean(False)
            if framing == "tcp":
                p.boolean(True)
            for pdu in requests_for(pr):
                p.uint8(0x05)  # framed, to the first served unit
                p.integral(0, 260, len(pdu))
                p.data(pdu)
            broken = rtu(unit, b"\x03\x00\x00\x00\x01")[:-1] + b"\x00"
            p.uint8(0x00)
            p.integral(0, 260, len(broken))
            p.data(broken)
            write("slave", p.bytes(), out_dir)

    # slave_request: the same requests one per input (framed for the first served unit), and the broken copy.
    for index, pr in enumerate(all_profiles):
        unit = max(1, min(pr.get("line", {}).get("unit_min", 1), 247))
        for framing_index, framing in enumerate(framings):
            if framing != "tcp" and index % 4 != 0:
                continue
            broken = rtu(unit, b"\x03\x00\x00\x00\x01")[:-1] + b"\x00"
            for shape, body in [(0x05, pdu) for pdu in requests_for(pr)] + [(0x00, broken)]:
                p = Provider()
                p.integral(0, len(all_profiles) - 1, index)
                p.integral(0, 2, framing_index)
                if framing == "tcp":
                    p.boolean(True)
                p.uint8(shape)
                p.integral(0, 0xFFFF, 1)
                p.data(body)
                write("slave_request", p.bytes(), out_dir)

    # frame_text: the manuals' examples file as it is, and the same frames as frames-file lines over MBAP and
    # in ASCII (written as text, CR LF spelled \r\n as on a command line).
    write("frame_text", open(os.path.join(ROOT, "captures", "manual-examples.txt"), "rb").read(), out_dir)
    lines = "".join("tcp %s # example %d over MBAP\n" % (adu.hex(" ").upper(), i + 1) for i, adu in enumerate(mbap))
    lines += "".join("ascii %s\n" % ascii_frame(0x11, pdu_of("rtu", f)).decode().replace("\r\n", "\\r\\n")
                     for f in rtu_frames)
    write("frame_text", lines.encode(), out_dir)

    # reply: the manual's requests and the responses it gives for them (000:330-484), to an MK instrument and
    # the generic profile, framed for the profile's unit, on each framing; over Modbus/TCP also with a late
    # reply to the request before in front of each (one transaction id behind).
    pdus = [pdu_of(f, b) for f, b in examples]
    pairs = [(0, 1), (2, 3), (4, 4), (5, 5), (6, 6), (7, 8), (9, 10), (0, 11)]
    for index, pr in enumerate(all_profiles):
        if pr["id"] not in ("mmk-2030", "modbus"):
            continue
        for framing_index, framing in enumerate(framings):
            for late in ((False, True) if framing == "tcp" else (False,)):
                p = Provider()
                p.integral(0, len(all_profiles) - 1, index)
                p.integral(0, 2, framing_index)
                if framing == "tcp":
                    p.boolean(True)   # reached by an IP address
                    p.boolean(False)  # over a stream, not UDP
                for request, response in pairs:
                    p.uint8(0x05)  # framed, to the profile's unit
                    p.integral(0, 260, len(pdus[request]))
                    p.data(pdus[request])
                    p.integral(0, 4, 2 if late else 1)
                    for kind in ((0x0B, 0x09) if late else (0x09,)):  # framed from the unit; 0x0B: one behind
                        p.uint8(kind)
                        p.integral(0, 300, len(pdus[response]))
                        p.data(pdus[response])
                write("reply", p.bytes(), out_dir)
        # Over RTU and ASCII: every other request left unanswered, its reply arriving late in front of the
        # next request's own (set aside by what it answers: no transaction id).
        for framing_index, framing in enumerate(framings):
            if framing == "tcp":
                continue
            p = Provider()
            p.integral(0, len(all_profiles) - 1, index)
            p.integral(0, 2, framing_index)
            for (request, response), (later, later_response) in zip(pairs[0::2], pairs[1::2]):
                p.uint8(0x05)
                p.integral(0, 260, len(pdus[request]))
                p.data(pdus[request])
                p.integral(0, 4, 0)  # nothing came: owed
                p.uint8(0x05)
                p.integral(0, 260, len(pdus[later]))
                p.data(pdus[later])
                p.integral(0, 4, 2)
                for pdu in (pdus[response], pdus[later_response]):
                    p.uint8(0x09)
                    p.integral(0, 300, len(pdu))
                    p.data(pdu)
            write("reply", p.bytes(), out_dir)

    # check: the input is read from the front (profile, scheme, read-only, rule family, then one action per
    # request the scripted slave receives; fuzz/fuzz_check.cpp). Every family on every scheme against a slave
    # that answers as the device does (no actions), on profiles in turn; and every family once against a slave
    # that goes through each action with parameters from a fixed generator.
    families = 14
    chosen = [i for i, pr in enumerate(all_profiles)
              if pr["id"] in ("mmk-2030", "modbus", "cth2265i", "walchem-w600", "dmy-2017")]
    for family in range(families):
        for scheme in range(3):
            profile = chosen[(family + scheme) % len(chosen)]
            write("check", bytes([profile, scheme, family % 2, family]), out_dir)
        state = family + 1
        actions = bytearray()
        for n in range(96):
            state = (state * 1103515245 + 12345) & 0x7FFFFFFF
            actions += bytes([n % 13, (state >> 8) & 0xFF, (state >> 16) & 0x0F, (state >> 20) & 0xFF])
        write("check", bytes([chosen[family % len(chosen)], family % 3, 0, family]) + bytes(actions), out_dir)

    # slave_state and reproducer: the files as the programs wrote them.
    for text in state_files(mbscope):
        write("slave_state", text, out_dir)
    for text in reproducers(mbscope):
        write("reproducer", text, out_dir)
    return 0


def merge(fuzz_dir, out_dir, targets):
    """Minimise each target's corpus with libFuzzer's -merge=1 into corpus/<target>/."""
    for target in targets:
        binary = os.path.join(fuzz_dir, "fuzz_" + target)
        seeds = os.path.join(out_dir, target)
        final = os.path.join(ROOT, "corpus", target)
        if not os.path.exists(binary) or not os.path.isdir(seeds):
            continue
        merged = tempfile.mkdtemp()
        inputs = [seeds] + ([final] if os.path.isdir(final) else [])
        subprocess.run([binary, "-merge=1", "-max_len=%d" % (max_len(target) or 65536), merged] + inputs, check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                       env=ENV)
        shutil.rmtree(final, ignore_errors=True)
        shutil.copytree(merged, final)
        shutil.rmtree(merged)
        print("%s: %d files" % (target, len(os.listdir(final))))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mbscope", required=True, help="the mbscope binary (for the profiles' maps)")
    parser.add_argument("--merge", metavar="FUZZ_DIR", help="folder of the fuzz_* binaries: minimise with -merge=1")
    parser.add_argument("--only", nargs="+", choices=TARGETS, default=TARGETS,
                        help="merge these targets' corpora only (the others stay as they are)")
    args = parser.parse_args()
    if args.merge:
        with tempfile.TemporaryDirectory() as seeds:
            build(args.mbscope, seeds)
            merge(args.merge, seeds, args.only)
    else:
        build(args.mbscope, os.path.join(ROOT, "corpus"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
