#!/usr/bin/env python3
"""Seed inputs for the KLV fuzzer, made at run time from the shared data folder (never copied
into the repository): the KLV payloads of the data streams of MPEG-TS files, and the MISB ST 0601
per-tag vectors as one-item local sets. Used by run-fuzzers.sh.

  make_seeds.py ts-klv OUT_DIR FILE.ts...     KLV PES payloads (at most 8 distinct per file)
  make_seeds.py st0601-vectors OUT_DIR FILE.json
"""
import json
import os
import sys

PES_KLV_STREAM_IDS = (0xBD, 0xFC)  # private stream 1 (asynchronous KLV), metadata (synchronous)


def ts_klv_payloads(data, limit=8):
    """PES payloads of the KLV streams of a 188-byte-packet transport stream."""
    pending = {}  # pid -> bytearray of the PES packet being gathered
    found = []

    def flush(pid):
        pes = pending.pop(pid, None)
        if pes is None or len(pes) < 9:
            return
        payload = bytes(pes[9 + pes[8]:])
        if payload and payload not in found:
            found.append(payload)

    for offset in range(0, len(data) - 187, 188):
        packet = data[offset:offset + 188]
        if packet[0] != 0x47:
            continue
        pid = ((packet[1] & 0x1F) << 8) | packet[2]
        start = bool(packet[1] & 0x40)
        control = (packet[3] >> 4) & 3
        if control in (0, 2):
            continue
        body = 4
        if control == 3:
            body += 1 + packet[4]
        payload = packet[body:]
        if start:
            flush(pid)
            if payload[:3] == b"\x00\x00\x01" and len(payload) > 3 and \
                    payload[3] in PES_KLV_STREAM_IDS:
                pending[pid] = bytearray(payload)
        elif pid in pending:
            pending[pid] += payload
        if len(found) >= limit:
            break
    for pid in list(pending):
        flush(pid)
    return found[:limit]


def write(out_dir, name, data):
    with open(os.path.join(out_dir, name), "wb") as out:
        out.write(data)


def main(argv):
    if len(argv) < 4:
        print(__doc__, file=sys.stderr)
        return 2
    mode, out_dir, inputs = argv[1], argv[2], argv[3:]
    os.makedirs(out_dir, exist_ok=True)
    count = 0
    if mode == "ts-klv":
        for path in inputs:
            with open(path, "rb") as f:
                data = f.read()
            stem = os.path.splitext(os.path.basename(path))[0]
            for i, payload in enumerate(ts_klv_payloads(data)):
                write(out_dir, "%s-klv%d.bin" % (stem, i), payload)
                count += 1
    elif mode == "st0601-vectors":
        with open(inputs[0]) as f:
            vectors = json.load(f)
        for i, vector in enumerate(vectors.get("tag_vectors", [])):
            write(out_dir, "st0601-tag%s-%d.bin" % (vector["tag"], i),
                  bytes.fromhex(vector["tlv_hex"]))
            count += 1
    else:
        print("unknown mode " + mode, file=sys.stderr)
        return 2
    print(count)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
