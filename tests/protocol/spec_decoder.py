#!/usr/bin/env python3
"""Independent decoder of dentmark protocol frames, written from docs/protocol.md
alone (no code shared with the C++ codec). Decodes every golden vector and compares
it with tests/data/protocol/golden.json; exits 1 on any difference.

    spec_decoder.py DATA_DIR            check the golden vectors
    spec_decoder.py --dump FILE.dml     print one frame as JSON
"""
import hashlib
import hmac
import json
import math
import struct
import sys
from pathlib import Path


def crc32c(data):
    crc = 0xFFFFFFFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0x82F63B78 if crc & 1 else crc >> 1
    return crc ^ 0xFFFFFFFF


class Reader:
    def __init__(self, data, pos, end):
        self.data, self.pos, self.end = data, pos, end

    def take(self, n):
        if self.pos + n > self.end:
            raise ValueError(f"byte {self.pos}: field of {n} bytes beyond its bounds")
        b = self.data[self.pos:self.pos + n]
        self.pos += n
        return b

    def u8(self): return self.take(1)[0]
    def u16(self): return struct.unpack("<H", self.take(2))[0]
    def u32(self): return struct.unpack("<I", self.take(4))[0]
    def u64(self): return struct.unpack("<Q", self.take(8))[0]

    def f64(self):
        v = struct.unpack("<d", self.take(8))[0]
        if not math.isfinite(v):
            raise ValueError(f"byte {self.pos - 8}: not finite")
        return v

    def vec3(self): return [self.f64() for _ in range(3)]

    def str8(self):
        s = self.take(self.u8())
        if any(c < 0x20 or c > 0x7E for c in s):
            raise ValueError(f"byte {self.pos - len(s)}: not printable ASCII")
        return s.decode("ascii")

    def zero(self, n):
        if any(self.take(n)):
            raise ValueError(f"byte {self.pos - n}: reserved bytes not 0")


TYPES = {1: "DefectList", 2: "Ack", 3: "MarkReport", 4: "Status", 5: "Error"}
RECORD_SIZE = {1: 88, 3: 48}
CLASSES = ["dent", "bump", "hole", "design_feature", "noise"]
OUTCOMES = ["marked", "skipped", "failed"]
REASONS = ["none", "not_markable", "out_of_reach", "tracking_lost", "robot_fault", "emergency_stop", "timeout",
           "aborted"]
STATES = ["idle", "job_received", "tracking", "marking", "done", "safe"]
CODES = {1: "malformed_frame", 2: "unauthenticated", 3: "unsupported", 4: "busy", 5: "internal"}


def decode(data, key=None):
    if data[:4] != b"DMKL":
        raise ValueError("bad magic")
    h = Reader(data, 4, 32)
    major, minor, mtype, flags, record_size, plen, seq = h.u8(), h.u8(), h.u16(), h.u16(), h.u16(), h.u32(), h.u64()
    send_time = h.f64()
    if major != 1:
        raise ValueError("unsupported version")
    if mtype not in TYPES or flags & ~1:
        raise ValueError("bad enum value")
    signed = bool(flags & 1)
    size = 32 + plen + (32 if signed else 0) + 4
    if size > 1 << 20 or len(data) != size:
        raise ValueError("bad length")
    if crc32c(data[:-4]) != struct.unpack("<I", data[-4:])[0]:
        raise ValueError("bad CRC")
    if key is not None:
        if not signed or not hmac.compare_digest(hmac.new(key, data[:32 + plen], hashlib.sha256).digest(),
                                                 data[32 + plen:32 + plen + 32]):
            raise ValueError("bad HMAC")
    known = RECORD_SIZE.get(mtype, 0)
    if (minor <= 1 and record_size != known) or record_size < known or (known == 0 and record_size != 0):
        raise ValueError("bad record size")
    p = Reader(data, 32, 32 + plen)
    head_size = p.u16()
    head = Reader(data, p.pos, p.pos + head_size)
    p.take(head_size)
    m = {}
    if mtype == 1:
        m = {"job_id": head.u64(), "scan_time": head.f64(), "panel_id": head.str8(), "frame": head.str8()}
    elif mtype == 2:
        m = {"job_id": head.u64(), "acked_sequence": head.u64(), "count": head.u32(), "digest": head.take(32).hex()}
    elif mtype == 3:
        m = {"job_id": head.u64()}
    elif mtype == 4:
        m = {"state": STATES[head.u8()], "protocol_major": head.u8(), "protocol_minor": head.u8()}
        head.zero(1)
        m.update(fault_bits=head.u32(), job_id=head.u64(), uptime=head.f64(), firmware_version=head.str8())
        if minor >= 1:
            m.update(defects_total=head.u32(), defects_reported=head.u32())
    elif mtype == 5:
        m = {"code": CODES[head.u16()]}
        head.zero(2)
        m.update(byte_offset=head.u32(), job_id=head.u64(), offending_sequence=head.u64(), text=head.str8())
    if minor <= 1 and head.pos != head.end:
        raise ValueError("head_size larger than the fields")
    count = p.u32()
    if count > 4096 or count * record_size != p.end - p.pos:
        raise ValueError("bad record count")
    records = []
    for _ in range(count):
        r = Reader(data, p.pos, p.pos + record_size)
        p.take(record_size)
        if mtype == 1:
            rec = {"id": r.u32(), "class": CLASSES[r.u8()]}
            r.zero(3)
            rec.update(position=r.vec3(), normal=r.vec3(), diameter=r.f64(), height=r.f64(), area=r.f64(),
                       score=r.f64())
            if abs(math.sqrt(sum(x * x for x in rec["normal"])) - 1) > 1e-6:
                raise ValueError("normal not unit")
        else:
            rec = {"defect_id": r.u32(), "outcome": OUTCOMES[r.u8()], "reason": REASONS[r.u8()]}
            r.zero(2)
            rec.update(time=r.f64(), tool_position=r.vec3(), estimated_error=r.f64())
        records.append(rec)
    if mtype == 1:
        m["defects"] = records
    elif mtype == 3:
        m["marks"] = records
    return {"type": TYPES[mtype], "sequence": seq, "send_time": send_time, "signed": signed, "message": m}


def read_key(path):
    text = "".join(l.split("#")[0] if not l.strip().startswith("#") else "" for l in path.read_text().splitlines())
    return bytes.fromhex("".join(text.split()))


def main(argv):
    if len(argv) == 3 and argv[1] == "--dump":
        print(json.dumps(decode(Path(argv[2]).read_bytes()), indent=2))
        return 0
    data_dir = Path(argv[1])
    golden = json.loads((data_dir / "golden.json").read_text())
    key = read_key(data_dir / golden["key_file"])
    failures = 0
    for name, want in golden["vectors"].items():
        want = dict(want)
        if "same_message_as" in want:
            want["message"] = golden["vectors"][want.pop("same_message_as")]["message"]
        got = decode((data_dir / name).read_bytes(), key if want["signed"] else None)
        if got != want:
            failures += 1
            print(f"{name}: decoded\n{json.dumps(got, indent=1)}\nexpected\n{json.dumps(want, indent=1)}")
        else:
            print(f"{name}: ok")
    # The signed vector must fail with another key.
    try:
        decode((data_dir / "defect_list_signed.dml").read_bytes(), bytes(32))
        print("defect_list_signed.dml: accepted with a wrong key")
        failures += 1
    except ValueError:
        pass
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
