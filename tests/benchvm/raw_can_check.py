#!/usr/bin/env python3
"""SocketCAN raw sockets inside the bench VM (called by guest_checks.sh).

usage: raw_can_check.py CAN_IF ROUTED_IF
  - a raw socket on CAN_IF accepts CAN_RAW_ERR_FILTER = CAN_ERR_MASK (error frames enabled);
  - a frame sent on one raw socket is received by another on the same interface;
  - a frame sent on CAN_IF arrives on ROUTED_IF (a cangw rule CAN_IF -> ROUTED_IF is set).
Prints one line per check; exits 1 on the first failure.
"""
import socket
import struct
import sys

CAN_ERR_MASK = 0x1FFFFFFF
CAN_RAW_ERR_FILTER = getattr(socket, "CAN_RAW_ERR_FILTER", 2)  # linux/can/raw.h; not in 3.11
FRAME = struct.Struct("=IB3x8s")  # struct can_frame: id, dlc, pad, data


def open_raw(ifname, timeout_s=2.0):
    s = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
    s.settimeout(timeout_s)
    s.bind((ifname,))
    return s


def frame(can_id, data):
    return FRAME.pack(can_id, len(data), data.ljust(8, b"\0"))


def unpack(raw):
    can_id, dlc, data = FRAME.unpack(raw)
    return can_id, data[:dlc]


def main():
    can_if, routed_if = sys.argv[1], sys.argv[2]

    listener = open_raw(can_if)
    listener.setsockopt(socket.SOL_CAN_RAW, CAN_RAW_ERR_FILTER,
                        struct.pack("=I", CAN_ERR_MASK))
    got = struct.unpack("=I", listener.getsockopt(socket.SOL_CAN_RAW,
                                                  CAN_RAW_ERR_FILTER, 4))[0]
    if got != CAN_ERR_MASK:
        sys.exit(f"FAIL: CAN_RAW_ERR_FILTER reads back {got:#x}")
    print(f"ok: CAN_RAW_ERR_FILTER = {CAN_ERR_MASK:#x} set on {can_if} (error frames enabled)")

    routed = open_raw(routed_if)
    sender = open_raw(can_if)
    sender.send(frame(0x701, b"\x05"))  # a CANopen heartbeat: node 1, operational
    can_id, data = unpack(listener.recv(16))
    if (can_id, data) != (0x701, b"\x05"):
        sys.exit(f"FAIL: {can_if} received id {can_id:#x} data {data.hex()}")
    print(f"ok: raw socket frame 701#05 received on {can_if}")
    can_id, data = unpack(routed.recv(16))
    if (can_id, data) != (0x701, b"\x05"):
        sys.exit(f"FAIL: {routed_if} received id {can_id:#x} data {data.hex()}")
    print(f"ok: cangw routed 701#05 from {can_if} to {routed_if}")


if __name__ == "__main__":
    main()
