"""Dynamixel AX-12 bus emulator on a pseudo-terminal (Protocol 1.0), for tests and trying the nodes.

    ros2 run hardware_drivers dynamixel_emulator --port /tmp/m3/arm [--ids 1,2,3,4,5,6]
        [--stall 6:400] [--drop-goals 0.2] [--packet-loss 0.05] [--seed 1]

One pty is one bus with several servos. Each servo keeps an AX-12 control table (factory
defaults) and answers PING, READ, WRITE, REG_WRITE/ACTION, RESET and SYNC_WRITE with status
packets, honouring the Status Return Level; a packet with a bad checksum is answered with the
checksum error bit, a goal outside the CW/CCW angle limits with the angle-limit bit (the goal is
not taken), a value out of range with the range bit. With torque enabled a servo moves its present
position toward the goal at the Moving Speed (0.111 rpm per unit, 0 = full speed), and reports
present speed, load, voltage, temperature and the Moving flag.

``--stall ID:POSITION`` models an object between the gripper's fingers: the servo stops at
POSITION when it closes past it and reports a load.

A real bus loses a packet now and then (noise, a servo busy when it arrives): ``--drop-goals P``
makes each servo miss a goal write (its part of a SYNC_WRITE, or a WRITE to the goal position) with
probability P, ``--packet-loss P`` any instruction addressed to it; a missed instruction is neither
carried out nor answered. The draws come from ``--seed``.

Control lines on stdin: ``error ID overload|overheat|voltage|none`` (a standing fault; overload and
overheating switch torque off as the Alarm Shutdown register says), ``mute ID on|off`` (the servo
stops answering), ``stall ID POSITION|none``, ``corrupt N`` (next N status packets with a bad
checksum), ``drop-goals P``, ``packet-loss P``, ``garbage N``, ``silence S``, ``unplug S``, ``plug``,
``quit``.
Events on stdout: ``ready PATH``, ``goal ID POSITION SPEED from PRESENT`` (PRESENT: where the servo
was when the goal came), ``torque ID 0|1``, ``missed ID WHAT``
(a dropped instruction: ``goal`` or the instruction's name).
"""

from __future__ import annotations

import argparse
import sys

from hardware_drivers import dynamixel_protocol as dx
from hardware_drivers.dynamixel_protocol import AX12, ErrorBit, Instruction
from hardware_drivers.emulators.pty_device import EmulatorApp, common_arguments, run_emulator

MOTION_PERIOD = 0.01
FULL_SPEED_UNITS = 1023  # Moving Speed 0 means the servo's maximum: about 114 rpm unloaded
POSITIONS_PER_SPEED_UNIT = dx.RAD_S_PER_SPEED_UNIT / dx.RAD_PER_POSITION  # positions/s per unit
FIELDS = {f.address: f for f in dx.AX12_FIELDS}


class Servo:
    def __init__(self, servo_id: int) -> None:
        self.table = bytearray(dx.CONTROL_TABLE_SIZE)
        for f in dx.AX12_FIELDS:
            self.table[f.address : f.address + f.size] = f.default.to_bytes(f.size, "little")
        self.table[AX12.ID] = servo_id
        self.position = float(self.word(AX12.PRESENT_POSITION))
        self.fault = ErrorBit(0)  # standing conditions: voltage, overheating, overload
        self.muted = False
        self.stall: int | None = None
        self.stall_side = 1.0  # the side of the stall position the servo is on (the object is beyond)
        self.registered: tuple[int, bytes] | None = None

    @property
    def servo_id(self) -> int:
        return self.table[AX12.ID]

    def word(self, address: int) -> int:
        return self.table[address] | self.table[address + 1] << 8

    def set_word(self, address: int, value: int) -> None:
        self.table[address : address + 2] = int(value).to_bytes(2, "little")

    def write(self, address: int, data: bytes) -> ErrorBit:
        """Apply a WRITE; returns the error bits of the reply (the write is refused on error)."""
        end = address + len(data)
        if end > dx.CONTROL_TABLE_SIZE or not data:
            return ErrorBit.RANGE
        proposed = bytearray(self.table)
        proposed[address:end] = data
        for f in dx.AX12_FIELDS:
            if f.address + f.size <= address or f.address >= end:
                continue
            value = int.from_bytes(proposed[f.address : f.address + f.size], "little")
            if not f.writable:
                return ErrorBit.RANGE
            if f.size == 2 and value > 1023 and f.address != AX12.MOVING_SPEED:
                return ErrorBit.RANGE
            if f.address == AX12.MOVING_SPEED and value > 2047:
                return ErrorBit.RANGE
            if f.address == AX12.TORQUE_ENABLE and value > 1:
                return ErrorBit.RANGE
        goal = proposed[AX12.GOAL_POSITION] | proposed[AX12.GOAL_POSITION + 1] << 8
        cw, ccw = self.word(AX12.CW_ANGLE_LIMIT), self.word(AX12.CCW_ANGLE_LIMIT)
        touches_goal = address <= AX12.GOAL_POSITION + 1 and end > AX12.GOAL_POSITION
        if touches_goal and not cw <= goal <= ccw:
            return ErrorBit.ANGLE_LIMIT
        if proposed[AX12.TORQUE_ENABLE] and self.fault & (ErrorBit.OVERLOAD | ErrorBit.OVERHEATING):
            proposed[AX12.TORQUE_ENABLE] = 0  # the alarm keeps the torque off while the cause lasts
        self.table[:] = proposed
        return ErrorBit(0)

    def inject(self, fault: str) -> None:
        bits = {"overload": ErrorBit.OVERLOAD, "overheat": ErrorBit.OVERHEATING,
                "voltage": ErrorBit.INPUT_VOLTAGE, "none": ErrorBit(0)}
        if fault not in bits:
            raise ValueError("fault must be overload, overheat, voltage or none")
        self.fault = bits[fault]
        self.table[AX12.PRESENT_TEMPERATURE] = 75 if fault == "overheat" else 35
        self.table[AX12.PRESENT_VOLTAGE] = 150 if fault == "voltage" else 120
        if self.fault & ErrorBit(self.table[AX12.ALARM_SHUTDOWN]):
            self.table[AX12.TORQUE_ENABLE] = 0
            self.set_word(AX12.TORQUE_LIMIT, 0)

    def move(self, dt: float) -> None:
        goal = self.word(AX12.GOAL_POSITION)
        speed_units = self.word(AX12.MOVING_SPEED) & 0x3FF or FULL_SPEED_UNITS
        velocity = 0.0
        load = 0.0
        if self.stall is not None and abs(self.position - self.stall) >= 0.5:
            self.stall_side = 1.0 if self.position > self.stall else -1.0
        blocked_side = -self.stall_side if self.stall is not None else 0.0
        pressing = self.stall is not None and abs(self.position - self.stall) < 0.5 \
            and (goal - self.stall) * blocked_side > 0.5
        if self.table[AX12.TORQUE_ENABLE] and abs(goal - self.position) > 0.5 and not pressing:
            step = speed_units * POSITIONS_PER_SPEED_UNIT * dt
            direction = 1.0 if goal > self.position else -1.0
            target = self.position + direction * min(step, abs(goal - self.position))
            if self.stall is not None and (target - self.stall) * blocked_side > 0:
                target = float(self.stall)  # the fingers close on the object
            velocity = (target - self.position) / dt * dx.RAD_PER_POSITION
            load = 0.1 * direction
            self.position = target
        if self.table[AX12.TORQUE_ENABLE] and pressing:
            load = 0.6 * blocked_side  # squeezing the object
        self.set_word(AX12.PRESENT_POSITION, round(self.position))
        self.set_word(AX12.PRESENT_SPEED, dx.signed_speed_to_raw(velocity))
        self.set_word(AX12.PRESENT_LOAD, dx.load_fraction_to_raw(load))
        self.table[AX12.MOVING] = 1 if abs(velocity) > 1e-6 else 0


class DynamixelEmulator(EmulatorApp):
    def __init__(self, link: str, baud: int, ids: list[int], stalls: dict[int, int], seed: int,
                 drop_goals: float = 0.0, packet_loss: float = 0.0) -> None:
        super().__init__(link, baud, seed)
        self.servos = {i: Servo(i) for i in ids}
        for servo_id, position in stalls.items():
            self.servos[servo_id].stall = position
        self.parser = dx.PacketParser()
        self.drop_goals = drop_goals  # probability that a servo misses a goal write
        self.packet_loss = packet_loss  # probability that a servo misses any instruction
        self._next_motion = 0.0

    def misses(self, servo: Servo, instruction: int, address: int | None, size: int) -> bool:
        """Whether `servo` misses this instruction (as the drop settings say); reported when it does."""
        touches_goal = address is not None and address <= AX12.GOAL_POSITION + 1 \
            and address + size > AX12.GOAL_POSITION
        if touches_goal and self.drop_goals > 0 and self.rng.random() < self.drop_goals:
            self.emit(f"missed {servo.servo_id} goal")
            return True
        if self.packet_loss > 0 and self.rng.random() < self.packet_loss:
            self.emit(f"missed {servo.servo_id} {_instruction_name(instruction)}")
            return True
        return False

    def on_plugged(self) -> None:
        self.parser = dx.PacketParser()

    def reply(self, servo: Servo, error: int, params: bytes = b"") -> None:
        packet = bytearray(dx.status_packet(servo.servo_id, error | servo.fault, params))
        if self.take_corruption():
            packet[-1] ^= 0x5A
        self.send(bytes(packet))

    def on_bytes(self, data: bytes, now: float) -> None:
        packets = self.parser.feed(data)
        for servo_id in self.parser.rejected_ids:
            servo = self.servos.get(servo_id)
            if servo is not None and not servo.muted:
                self.reply(servo, ErrorBit.CHECKSUM)
        self.parser.rejected_ids.clear()
        for packet in packets:
            self.execute(packet)

    def execute(self, packet: dx.Packet) -> None:
        if packet.servo_id == dx.BROADCAST_ID:
            if packet.code == Instruction.SYNC_WRITE and len(packet.params) >= 2:
                address, size = packet.params[0], packet.params[1]
                body = packet.params[2:]
                for k in range(0, len(body) - size, size + 1):
                    servo = self.servos.get(body[k])
                    if servo is not None and not servo.muted \
                            and not self.misses(servo, packet.code, address, size):
                        self._write(servo, address, bytes(body[k + 1 : k + 1 + size]))
            elif packet.code == Instruction.ACTION:
                for servo in self.servos.values():
                    self._action(servo)
            return
        servo = self.servos.get(packet.servo_id)
        if servo is None or servo.muted:
            return
        params = packet.params
        writes = packet.code in (Instruction.WRITE, Instruction.REG_WRITE) and len(params) > 0
        if self.misses(servo, packet.code, params[0] if writes else None, len(params) - 1):
            return
        level = servo.table[AX12.STATUS_RETURN_LEVEL]
        if packet.code == Instruction.PING:
            self.reply(servo, 0)
        elif packet.code == Instruction.READ:
            if len(params) != 2 or params[0] + params[1] > dx.CONTROL_TABLE_SIZE:
                self.reply(servo, ErrorBit.RANGE)
            elif level >= 1:
                self.reply(servo, 0, bytes(servo.table[params[0] : params[0] + params[1]]))
        elif packet.code == Instruction.WRITE:
            error = self._write(servo, params[0], bytes(params[1:])) if params else ErrorBit.INSTRUCTION
            if level >= 2:
                self.reply(servo, error)
        elif packet.code == Instruction.REG_WRITE:
            servo.registered = (params[0], bytes(params[1:])) if params else None
            servo.table[AX12.REGISTERED] = 1
            if level >= 2:
                self.reply(servo, 0)
        elif packet.code == Instruction.ACTION:
            error = 0 if servo.registered else ErrorBit.INSTRUCTION
            self._action(servo)
            if level >= 2:
                self.reply(servo, error)
        elif packet.code == Instruction.RESET:
            servo_id = servo.servo_id
            self.servos[servo_id] = Servo(servo_id)
            if level >= 2:
                self.reply(self.servos[servo_id], 0)
        elif level >= 2:
            self.reply(servo, ErrorBit.INSTRUCTION)

    def _action(self, servo: Servo) -> None:
        if servo.registered:
            self._write(servo, *servo.registered)
            servo.registered = None
            servo.table[AX12.REGISTERED] = 0

    def _write(self, servo: Servo, address: int, data: bytes) -> ErrorBit:
        torque_before = servo.table[AX12.TORQUE_ENABLE]
        goal_before = (servo.word(AX12.GOAL_POSITION), servo.word(AX12.MOVING_SPEED))
        error = servo.write(address, data)
        if servo.table[AX12.TORQUE_ENABLE] != torque_before:
            self.emit(f"torque {servo.servo_id} {servo.table[AX12.TORQUE_ENABLE]}")
        goal_after = (servo.word(AX12.GOAL_POSITION), servo.word(AX12.MOVING_SPEED))
        if goal_after != goal_before:
            self.emit(f"goal {servo.servo_id} {goal_after[0]} {goal_after[1]} from {round(servo.position)}")
        return error

    def tick(self, now: float) -> None:
        if now >= self._next_motion:
            dt = MOTION_PERIOD if self._next_motion == 0.0 else now - self._next_motion + MOTION_PERIOD
            self._next_motion = now + MOTION_PERIOD
            for servo in self.servos.values():
                servo.move(min(dt, 0.1))

    def command(self, words: list[str], now: float) -> bool:
        verb = words[0]
        if verb == "error":
            self._servo(words[1]).inject(words[2])
            self.emit(f"error {words[1]} {words[2]}")
        elif verb == "mute":
            self._servo(words[1]).muted = words[2] == "on"
            self.emit(f"mute {words[1]} {words[2]}")
        elif verb == "stall":
            self._servo(words[1]).stall = None if words[2] == "none" else int(words[2])
            self.emit(f"stall {words[1]} {words[2]}")
        elif verb == "drop-goals":
            self.drop_goals = _probability(words[1])
            self.emit(f"drop-goals {self.drop_goals:g}")
        elif verb == "packet-loss":
            self.packet_loss = _probability(words[1])
            self.emit(f"packet-loss {self.packet_loss:g}")
        else:
            return False
        return True

    def _servo(self, text: str) -> Servo:
        servo = self.servos.get(int(text))
        if servo is None:
            raise ValueError(f"no servo {text} on this bus")
        return servo


def _instruction_name(code: int) -> str:
    try:
        return Instruction(code).name.lower()
    except ValueError:
        return f"instruction_{code}"


def _probability(text: str) -> float:
    value = float(text)
    if not 0.0 <= value <= 1.0:
        raise ValueError(f"a probability must be in [0, 1], got {text}")
    return value


def _stall(text: str) -> tuple[int, int]:
    servo_id, _, position = text.partition(":")
    return int(servo_id), int(position)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="dynamixel_emulator", description=__doc__.split("\n\n")[0])
    common_arguments(parser, "/tmp/hardware_drivers/arm", 1000000)
    parser.add_argument("--ids", default="1,2,3,4,5,6", help="servo ids on the bus (default 1..6)")
    parser.add_argument("--stall", action="append", type=_stall, default=[], metavar="ID:POSITION",
                        help="an object stops servo ID at POSITION (a tile in the gripper)")
    parser.add_argument("--drop-goals", type=_probability, default=0.0, metavar="P",
                        help="probability that a servo misses a goal write (default 0)")
    parser.add_argument("--packet-loss", type=_probability, default=0.0, metavar="P",
                        help="probability that a servo misses any instruction (default 0)")
    args = parser.parse_args(argv)
    ids = [int(v) for v in args.ids.split(",") if v.strip()]
    return run_emulator(
        lambda a: DynamixelEmulator(a.port, a.baud, ids, dict(a.stall), a.seed, a.drop_goals, a.packet_loss),
        args,
    )


if __name__ == "__main__":
    sys.exit(main())
