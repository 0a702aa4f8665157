#!/usr/bin/env python3
"""Writes the seed corpus of the fuzz targets (tests/fuzz/corpus/<target>/): a few valid
frames and exchanges in each target's input format (see the header comment of
fuzz_can_frames.cpp and fuzz_sdo_client.cpp), valid USB reports (docs/usb-protocol.md) for
fuzz_usb_in_report, every file under config/ (devices, scenes, model definitions) with
fuzz_config's leading mode byte, and fuzz_config's TOML dictionary (config.dict: every quoted
identifier of rt/config/src, which holds every key, table and choice, plus TOML syntax).
Run from anywhere; rewrites the files. The model image seeds come from make_image_seeds.sh
(they need modelc)."""
import pathlib
import re
import shutil
import struct

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent.parent
CAN_ERR_FLAG = 0x20000000


def can_record(can_id, data, step=10):
    """fuzz_can_frames: can_id u32, len u8, data[8], time step u16 (100 us units)."""
    payload = bytes(data) + bytes(8 - len(data))
    return struct.pack("<IB", can_id, len(data)) + payload + struct.pack("<H", step)


def sdo_record(data, flags=0x08, step=1, spare=0):
    """fuzz_sdo_client: flags u8, 8 data bytes, time step u16 (1 ms units), spare u8."""
    return bytes([flags]) + bytes(data) + bytes(8 - len(data)) + struct.pack("<HB", step, spare)


def write(target, name, content):
    folder = HERE / "corpus" / target
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_bytes(content)


def can_frames():
    t = "fuzz_can_frames"
    write(t, "nmt_start_sync", can_record(0x000, [0x01, 0x05]) + can_record(0x080, []) + can_record(0x080, [3]))
    write(t, "heartbeats", can_record(0x705, [0x00]) + can_record(0x705, [0x7F]) + can_record(0x705, [0x05], 500)
          + can_record(0x706, [0x05], 2000))
    write(t, "emcy_overcurrent", can_record(0x085, [0x10, 0x23, 0x03, 1, 2, 3, 4, 5]))
    write(t, "error_bus_off", can_record(CAN_ERR_FLAG | 0x244, [0, 0x30, 0, 0, 0, 0, 200, 90]))
    # A drive walked to operation enabled by controlwords in RPDO1, then a fault and its reset.
    walk = b"".join(can_record(0x205, [cw & 0xFF, cw >> 8, 0, 0, 0, 0, 0, 0])
                    for cw in (0x0000, 0x0006, 0x0007, 0x000F, 0x000F))
    walk += can_record(0x205, [0x0F, 0, 0, 0x0F, 0, 0, 0, 0])  # data[3] = 0x0F raises a fault
    walk += b"".join(can_record(0x205, [cw, 0, 0, 0, 0, 0, 0, 0], 200) for cw in (0x00, 0x80, 0x06, 0x07, 0x0F))
    write(t, "cia402_walk", walk)
    write(t, "tpdo_sdo", can_record(0x185, [0x37, 0x02, 0x18, 0xFC, 0x40, 0xE2, 0x01, 0x00])
          + can_record(0x605, [0x40, 0x41, 0x60, 0x00]) + can_record(0x585, [0x80, 0, 0x20, 0, 0, 0, 2, 6]))


def sdo_client():
    t = "fuzz_sdo_client"
    # mode 0: download of 10 bytes answered by a server.
    write(t, "download_10", bytes([0, 10]) + sdo_record([0x60, 0x00, 0x20, 0x01]) + sdo_record([0x20])
          + sdo_record([0x30]))
    # mode 1: upload of 12 bytes.
    write(t, "upload_12", bytes([1, 12]) + sdo_record([0x41, 0x00, 0x20, 0x01, 12]) + sdo_record([0x00] + list(b"haptic "))
          + sdo_record([0x15] + list(b"drive")))
    # mode 1: expedited upload, then a timeout.
    write(t, "upload_expedited", bytes([1, 4]) + sdo_record([0x4B, 0x00, 0x20, 0x01, 0x37, 0x02])
          + sdo_record([0], flags=0x20, step=200))
    # mode 2: requests to the server: expedited write, segmented read of 0x1008, an unknown object.
    write(t, "server_requests", bytes([2, 0]) + sdo_record([0x2F, 0x60, 0x60, 0x00, 10])
          + sdo_record([0x40, 0x08, 0x10, 0x00]) + sdo_record([0x60]) + sdo_record([0x70])
          + sdo_record([0x40, 0x00, 0x30, 0x00]) + sdo_record([0x21, 0x00, 0x20, 0x01, 9])
          + sdo_record([0x00] + list(b"1234567")) + sdo_record([0x1B] + list(b"89")))
    # mode 3: client and server back to back, 100 bytes, no losses.
    write(t, "pair_100", bytes([3, 100]) + b"".join(sdo_record([0], flags=0, spare=i) for i in range(40)))


def crc8(data):
    """CRC-8/SMBUS (poly 0x07, init 0): the last byte of every USB report."""
    crc = 0
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x07) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


def usb_in_report(seq, out_seq, time_us, status, buttons, counts):
    """IN report: 'I', version 1, channel count, seq, out seq, time, status, buttons, i24 counts."""
    body = struct.pack("<BBBHHIHH", 0x49, 1, len(counts), seq, out_seq, time_us, status, buttons)
    for c in counts:
        body += (c & 0xFFFFFF).to_bytes(3, "little")
    body += bytes(63 - len(body))
    return body + bytes([crc8(body)])


def usb_out_report(seq, flags, currents):
    body = struct.pack("<BBBBH", 0x4F, 1, len(currents), flags, seq)
    body += b"".join(struct.pack("<h", c) for c in currents)
    body += bytes(63 - len(body))
    return body + bytes([crc8(body)])


def usb_identity(channels, firmware, watchdog_ms, frame_us, max_ma):
    body = struct.pack("<BBBBHHIHB", 0x44, 1, channels, 0, firmware, watchdog_ms, frame_us, max_ma, 0)
    return body + bytes([crc8(body)])


def usb_in_report_corpus():
    t = "fuzz_usb_in_report"
    write(t, "in_10_channels", usb_in_report(7, 6, 7000, 0x0002, 0x0001,
                                             [0, 1, -1, 4096, -4096, 2**23 - 1, -2**23, 12, 13, 14]))
    write(t, "in_16_channels", usb_in_report(0xFFFF, 0xFFFE, 0xFFFFFFFF, 0x0021, 0xFFFF, list(range(-8, 8))))
    write(t, "in_tripped_empty", usb_in_report(3, 2, 3000, 0x0001, 0, []))
    write(t, "out_10_channels", usb_out_report(9, 0x01, [100, -100, 0, 32767, -32768, 1, 2, 3, 4, 5]))
    write(t, "identity", usb_identity(10, 0x0100, 20, 1000, 3000))


def config_corpus():
    """fuzz_config: byte 0 = 0 device, 1 scene, 2 model definition; then the file's text."""
    t = "fuzz_config"
    shutil.rmtree(HERE / "corpus" / t, ignore_errors=True)
    for mode, sub in ((0, "devices"), (1, "scenes"), (2, "models")):
        for path in sorted((REPO / "config" / sub).glob("*.toml")):
            write(t, f"{sub}_{path.stem}", bytes([mode]) + path.read_bytes())


def config_dict():
    """-dict= of fuzz_config: libFuzzer's format, one "token" per line."""
    words = set()
    for source in sorted((REPO / "rt" / "config" / "src").glob("*.cpp")):
        words.update(re.findall(r'"([a-z][a-z0-9_]*)"', source.read_text()))
    syntax = ["[", "]", "[[", "]]", " = ", "=", "\\x0A", "#", ",", ".", "\\\"", "'",
              "\\\"\\\"\\\"", "'" * 3, "true", "false", "inf", "-inf", "nan", "0", "-1", "1e308",
              "1e-320", "0x7fffffffffffffff", "-9223372036854775808", "1979-05-27T07:32:00Z",
              "{ }", "[ ]", "builtin:", "../devices/sim.toml", "../models/duct.toml",
              "../models/liver.toml", "../models/catheter.toml", "../trajectories/wall_press.csv"]
    lines = ["# fuzz_config dictionary: written by make_seed_corpus.py from rt/config/src"]
    lines += [f'kw_{w}="{w}"' for w in sorted(words)]
    lines += [f'syntax_{i}="{token}"' for i, token in enumerate(syntax)]
    (HERE / "config.dict").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    config_corpus()
    config_dict()
    can_frames()
    sdo_client()
    usb_in_report_corpus()
