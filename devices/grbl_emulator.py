#!/usr/bin/env python3
"""GRBL 1.1h controller emulator on a pseudo-terminal (Python 3 standard library only).

Usage
-----
    python3 devices/grbl_emulator.py --link /tmp/grbl0 &

The first line printed on stdout is the path of the pty slave (e.g. /dev/pts/7);
with ``--link PATH`` a symlink PATH -> slave is also made (and removed on exit).
Point the rig's ``port`` at it (``[slide] port = "/tmp/grbl0"`` in rig.toml);
any baud rate works. Stop it with SIGTERM or SIGINT (``kill %1``).

The emulator answers like GRBL 1.1h firmware (gnea/grbl, build 20190830) on an
Arduino with a linear slide on X; Y and Z exist but nothing moves them unless
you command it. It follows the GRBL 1.1 interface documents and the firmware's
control flow (protocol.c, gcode.c, system.c, limits.c, motion_control.c):

* Banner ``\\r\\nGrbl 1.1h ['$' for help]\\r\\n`` at start and after every soft
  reset. Homing is enabled ($22=1, ``--no-homing`` sets $22=0, which also forces
  $20=0 as in the firmware), so the firmware starts in Alarm and sends
  ``[MSG:'$H'|'$X' to unlock]``; it does so after any reset that leaves it in Alarm.
* Lines: every ``\\r`` *and* every ``\\n`` ends a line, and an empty line is
  answered with ``ok`` (GRBL does this), so a client sending ``\\r\\n`` gets two
  ``ok`` per command; send ``\\n`` only (or start with ``--merge-crlf``). Each line
  gets exactly one ``ok`` / ``error:N``. Spaces and control characters are
  dropped, letters upper-cased, ``(...)`` and ``;...`` comments removed, lines
  over 79 characters get ``error:11``. The serial receive buffer holds 128 bytes
  (bytes past it are lost, as on the Arduino): stream with send-response or
  character counting.
* Real-time bytes, acted on at once, even inside a line: ``?`` status report,
  ``!`` feed hold, ``~`` cycle start, 0x18 soft reset, 0x85 jog cancel,
  0x90-0x9D feed/rapid/spindle overrides, 0xA0 coolant toggle. Other bytes >= 0x80
  are dropped. 0x84 (safety door) and 0x9E (spindle stop) are ignored.
* Status report, 3 decimals in mm ($13=0), rates in whole mm/min:
  ``<Idle|MPos:0.000,0.000,0.000|FS:0,0>`` with state Idle, Run, Hold:0 (hold
  complete), Hold:1 (decelerating), Jog, Home, Alarm, Check, Sleep. FS is the
  actual speed (0 when not moving) and the spindle speed. As GRBL 1.1h does, some
  reports carry ``|WCO:x,y,z`` (the first one after a reset, then every 10th when
  idle / 30th when moving) or ``|Ov:100,100,100`` (+ ``|A:S`` when the spindle is
  on); ``--plain-status`` leaves these out. $10=0 reports WPos, $10 bit 2 adds
  ``|Bf:blocks,bytes``. ``|Pn:X`` shows a pressed X limit switch.
  GRBL does not answer ``?`` during a homing cycle (one report, state Home, comes
  at its end) nor after a soft/hard limit alarm until a soft reset.
* Streaming: a motion line is answered ``ok`` as soon as it is queued in the
  15-block planner (when the planner is full the ``ok`` waits for a free block).
  M3/M4/M5, a new S, M8/M9, G4, G10, G28.1/G30.1, G92, G54..G59, G43.1/G49, M0/M2/M30
  wait until all queued motion has finished before they act and answer ``ok``.
* Feed hold ``!`` decelerates (Hold:1) to a stop (Hold:0); in Idle it goes to
  Hold:0 at once. While held, GRBL executes no further lines (they wait in the
  receive buffer and get their ``ok`` after ``~``).
* Soft reset 0x18: stops everything and flushes the planner and receive buffer;
  while moving (Run, Hold:1, Jog) it sends ``ALARM:3`` and ends in Alarm; during
  homing ``ALARM:6``. A line already executing (waiting for a sync, a dwell, room
  in the planner, homing) still gets its ``ok`` before the new banner.
* Motion: trapezoidal velocity profiles with look-ahead over the planner
  (junction deviation $11), acceleration $120-$122 (mm/s^2), max rate $110-$112
  (G0 and the cap for G1), step resolution $100-$102 (positions are multiples of
  one step). G0, G1, G2/G3 arcs, G4 P<seconds>, G17-G19, G20/G21 (inches
  converted), G38.2-G38.5 (no probe is wired: G38.2 ends with ALARM:5, G38.4/5
  give ALARM:4, G38.3 moves and reports [PRB:...:0]), G40, G43.1/G49, G53,
  G54-G59, G10 L2/L20, G28/G30 (+.1), G61, G80, G90/G91, G91.1, G92/G92.1,
  G93/G94, M0/M1/M2/M30, M3/M4/M5 S, M8/M9, T, N, F. Errors as gcode.c
  (error:1 letter expected, 2 bad number, 20 unsupported, 21 modal group, 22
  feed undefined, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32, 33, 34, 35, 36, 37, 38).
* ``$`` commands: ``$`` help, ``$$``, ``$N=value``, ``$#``, ``$G``, ``$I``,
  ``$I=``, ``$N``, ``$N0=``/``$N1=`` startup lines, ``$C`` check mode, ``$X``,
  ``$H``, ``$J=`` jogging, ``$SLP``, ``$RST=$``/``#``/``*``. G-code in Alarm
  gives ``error:9``; ``$H``/``$$`` etc. outside Idle/Alarm give ``error:8``.
* Homing ``$H`` (X axis only, as a build with HOMING_CYCLE_0 = X): seek at $25
  until the switch, pull off $27, locate at $24, pull off again, with the
  debounce delay $26 after each phase; state Home; no status reports meanwhile;
  then Idle and ``ok``. The carriage starts ``--home-distance`` mm (default 10)
  from its switch, so the first homing takes about 3 s with the defaults.
* Machine space (a choice of this emulator, say so to clients):
  default: X, Y and Z live in 0..+max travel ($130-$132, 200 mm); the X switch
  is at the negative end; this is GRBL built with HOMING_FORCE_SET_ORIGIN
  (``[OPT:VZ,15,128]``) and $23=7, and after $H the machine position is
  0.000,0.000,0.000.
  ``--negative-space``: stock GRBL: $23=0, the switch at the positive end,
  space -max travel..0, after $H X = -$27 (-1.000).
* Soft limits ($20=1): a motion target outside the space gives what GRBL 1.1
  gives: the machine stops (decelerating, if it was moving; position kept),
  ``ALARM:2`` then ``[MSG:Reset to continue]``; afterwards nothing is executed
  and ``?`` is not answered until a soft reset 0x18. Then the offending line's
  ``ok``, the banner and ``[MSG:'$H'|'$X' to unlock]``; state Alarm, where G-code
  gets ``error:9`` until ``$X`` (``[MSG:Caution: Unlocked]``, ``ok``) or ``$H``.
  A ``$J=`` jog outside the space gets ``error:15`` instead. Hard limits ($21=1)
  give ``ALARM:1`` (critical) when the carriage runs onto its switch.
* Spindle/laser: M3/M4 S<n> set the output (clamped to $30/$31 and scaled by the
  spindle override), M5 clears it; $32=1 laser mode (power only while moving
  with G1/G2/G3, M4 scaled by speed, off during a hold).
* Settings live in memory ("EEPROM") across soft resets, not across restarts.
  ``--setting N=V`` presets them; ``$RST=$`` restores this emulator's defaults:
  $0=10 $1=25 $2=0 $3=0 $4=0 $5=0 $6=0 $10=1 $11=0.010 $12=0.002 $13=0 $20=1
  $21=0 $22=1 $23=7 (0 with --negative-space) $24=100.000 $25=500.000 $26=250
  $27=1.000 $30=1000 $31=0 $32=0, and for X, Y, Z: $100-$102=250.000 steps/mm,
  $110-$112=6000.000 mm/min, $120-$122=500.000 mm/s^2, $130-$132=200.000 mm.
  (Stock GRBL has $110=500 and $120=10; with those a 100 mm G1 F3000 move is
  capped at 500 mm/min. Use ``--setting 110=500 --setting 120=10`` for them.)
* Timing: the client's bytes reach the firmware at the serial rate (``--baud``,
  115200: about 11.5 bytes/ms); an ALARM line is followed by GRBL's 500 ms pause.

Not emulated: step pulses and the step-level timing of the stepper ISR (motion
is integrated in 1 ms steps), safety door and parking, spindle stop override,
the [echo:] line, line numbers in reports, EEPROM write delays, the Arduino's
reset when the port is opened (DTR), baud rate and serial framing. Output sent
while no client has the port open stays in the pty buffer and is read by the
next client (so the first banner is not lost); a client that reopens the port
should flush its input or send 0x18 and wait for the banner.

Fault injection (line numbers count every line the client sends, from 1, as the
emulator receives them; a ``\\r\\n`` counts as two lines; real-time bytes are not
lines):
  --drop-ok N        the final ok/error of line N is not sent (repeatable)
  --garbage-after N  one garbage line ``\\x00\\xfe@@garbage@@\\r\\n`` follows the
                     answer to line N (repeatable)
  --silent-after N   after the answer to line N nothing more is sent (no ok, no
                     status reports, no banner), but input is still read and logged
  --vanish-after N   when line N arrives, the pty master is closed and the
                     emulator exits: the client's reads and writes fail (EIO)
  --log FILE         append every received line (stripped) to FILE, flushed at
                     once; with --log-realtime also real-time bytes as ``<?>``,
                     ``<!>``, ``<~>``, ``<0x18>``, ``<0x85>``, ... on lines of their own
  --time-scale X     multiply all motion, homing, dwell and alarm-delay durations by X

Other options: --no-homing, --negative-space, --home-distance MM, --setting N=V,
--baud B, --merge-crlf (take \r\n as one line end), --plain-status (no |WCO:/|Ov:
fields), --verbose (trace the traffic on stderr). See --help.
"""

import argparse
import errno
import math
import os
import select
import signal
import sys
import termios
import time
import tty

GRBL_VERSION = "1.1h"
GRBL_VERSION_BUILD = "20190830"
N_AXIS = 3
MM_PER_INCH = 25.4
RX_BUFFER_SIZE = 128
LINE_BUFFER_SIZE = 80
BLOCK_BUFFER_SLOTS = 15  # BLOCK_BUFFER_SIZE 16 minus one
MAX_LINE_NUMBER = 10000000
MAX_TOOL_NUMBER = 255
MAX_INT_DIGITS = 8
MINIMUM_FEED_RATE = 1.0  # mm/min
HOMING_AXIS_SEARCH_SCALAR = 1.5
HOMING_AXIS_LOCATE_SCALAR = 5.0
N_HOMING_LOCATE_CYCLE = 1
HOMING_CYCLE_MASK = 1  # X only
ARC_ANGULAR_TRAVEL_EPSILON = 5e-7
SIM_STEP = 0.001  # s of machine time per integration step
GARBAGE_LINE = b"\x00\xfe@@garbage@@\r\n"

# System states (bit flags, as system.h)
STATE_IDLE = 0
STATE_ALARM = 1 << 0
STATE_CHECK_MODE = 1 << 1
STATE_HOMING = 1 << 2
STATE_CYCLE = 1 << 3
STATE_HOLD = 1 << 4
STATE_JOG = 1 << 5
STATE_SAFETY_DOOR = 1 << 6
STATE_SLEEP = 1 << 7

SUSPEND_HOLD_COMPLETE = 1 << 0
SUSPEND_RETRACT_COMPLETE = 1 << 2
SUSPEND_MOTION_CANCEL = 1 << 6
SUSPEND_JOG_CANCEL = 1 << 7

STEP_CONTROL_EXECUTE_HOLD = 1 << 0
STEP_CONTROL_EXECUTE_SYS_MOTION = 1 << 1

EXEC_STATUS_REPORT = 1 << 0
EXEC_CYCLE_START = 1 << 1
EXEC_CYCLE_STOP = 1 << 2
EXEC_FEED_HOLD = 1 << 3
EXEC_RESET = 1 << 4
EXEC_SAFETY_DOOR = 1 << 5
EXEC_MOTION_CANCEL = 1 << 6
EXEC_SLEEP = 1 << 7

ALARM_HARD_LIMIT = 1
ALARM_SOFT_LIMIT = 2
ALARM_ABORT_CYCLE = 3
ALARM_PROBE_FAIL_INITIAL = 4
ALARM_PROBE_FAIL_CONTACT = 5
ALARM_HOMING_FAIL_RESET = 6
ALARM_HOMING_FAIL_PULLOFF = 8
ALARM_HOMING_FAIL_APPROACH = 9

# Status codes (report.h / interface.md)
OK = 0
E_EXPECTED_COMMAND_LETTER = 1
E_BAD_NUMBER_FORMAT = 2
E_INVALID_STATEMENT = 3
E_NEGATIVE_VALUE = 4
E_SETTING_DISABLED = 5
E_SETTING_STEP_PULSE_MIN = 6
E_IDLE_ERROR = 8
E_SYSTEM_GC_LOCK = 9
E_SOFT_LIMIT_ERROR = 10
E_OVERFLOW = 11
E_LINE_LENGTH_EXCEEDED = 14
E_TRAVEL_EXCEEDED = 15
E_INVALID_JOG_COMMAND = 16
E_UNSUPPORTED_COMMAND = 20
E_MODAL_GROUP_VIOLATION = 21
E_UNDEFINED_FEED_RATE = 22
E_COMMAND_VALUE_NOT_INTEGER = 23
E_AXIS_COMMAND_CONFLICT = 24
E_WORD_REPEATED = 25
E_NO_AXIS_WORDS = 26
E_INVALID_LINE_NUMBER = 27
E_VALUE_WORD_MISSING = 28
E_UNSUPPORTED_COORD_SYS = 29
E_G53_INVALID_MOTION_MODE = 30
E_AXIS_WORDS_EXIST = 31
E_NO_AXIS_WORDS_IN_PLANE = 32
E_INVALID_TARGET = 33
E_ARC_RADIUS_ERROR = 34
E_NO_OFFSETS_IN_PLANE = 35
E_UNUSED_WORDS = 36
E_G43_DYNAMIC_AXIS_ERROR = 37
E_MAX_VALUE_EXCEEDED = 38

# G-code parser constants (gcode.h)
MOTION_SEEK, MOTION_LINEAR, MOTION_CW_ARC, MOTION_CCW_ARC = 0, 1, 2, 3
MOTION_PROBE_TOWARD, MOTION_PROBE_TOWARD_NO_ERROR = 140, 141
MOTION_PROBE_AWAY, MOTION_PROBE_AWAY_NO_ERROR = 142, 143
MOTION_NONE = 80
NM_NONE, NM_DWELL, NM_SET_COORD_DATA, NM_GO_HOME_0 = 0, 4, 10, 28
NM_SET_HOME_0, NM_GO_HOME_1, NM_SET_HOME_1, NM_ABSOLUTE_OVERRIDE = 38, 30, 40, 53
NM_SET_COORD_OFFSET, NM_RESET_COORD_OFFSET = 92, 102
FLOW_RUNNING, FLOW_PAUSED, FLOW_M2, FLOW_M30 = 0, 3, 2, 30
SPINDLE_DISABLE, SPINDLE_CW, SPINDLE_CCW = 0, 1 << 4, 1 << 5
COOLANT_FLOOD, COOLANT_MIST = 1 << 6, 1 << 7
AXIS_CMD_NONE, AXIS_CMD_NON_MODAL, AXIS_CMD_MOTION, AXIS_CMD_TLO = 0, 1, 2, 3
(MG_G0, MG_G1, MG_G2, MG_G3, MG_G4, MG_G5, MG_G6, MG_G7, MG_G8, MG_G12, MG_G13,
 MG_M4, MG_M7, MG_M8) = range(14)
WORDS = "FIJKLNPRSTXYZ"
WORD_BIT = {c: 1 << i for i, c in enumerate(WORDS)}
AXIS_WORD_BITS = WORD_BIT["X"] | WORD_BIT["Y"] | WORD_BIT["Z"]

# Real-time commands
CMD_RESET, CMD_STATUS, CMD_CYCLE_START, CMD_FEED_HOLD = 0x18, 0x3F, 0x7E, 0x21
CMD_SAFETY_DOOR, CMD_JOG_CANCEL = 0x84, 0x85

# Settings as printed by report_grbl_settings(): number -> kind
# 'u' = integer (uint8), 'f' = 3 decimals, 'r' = rpm (0 decimals)
SETTING_KINDS = {0: "u", 1: "u", 2: "u", 3: "u", 4: "u", 5: "u", 6: "u", 10: "u", 11: "f",
                 12: "f", 13: "u", 20: "u", 21: "u", 22: "u", 23: "u", 24: "f", 25: "f",
                 26: "u", 27: "f", 30: "r", 31: "r", 32: "u"}
for _base in (100, 110, 120, 130):
    for _i in range(N_AXIS):
        SETTING_KINDS[_base + _i] = "f"
SETTING_ORDER = sorted(SETTING_KINDS)


def default_settings(negative_space, homing):
    s = {0: 10, 1: 25, 2: 0, 3: 0, 4: 0, 5: 0, 6: 0, 10: 1, 11: 0.010, 12: 0.002, 13: 0,
         20: 1, 21: 0, 22: 1, 23: 0 if negative_space else 7, 24: 100.0, 25: 500.0,
         26: 250, 27: 1.0, 30: 1000.0, 31: 0.0, 32: 0}
    for i in range(N_AXIS):
        s[100 + i] = 250.0    # steps/mm
        s[110 + i] = 6000.0   # max rate, mm/min
        s[120 + i] = 500.0    # acceleration, mm/s^2
        s[130 + i] = 200.0    # max travel, mm
    if not homing:
        s[22] = 0
        s[20] = 0
    return s


def c_round(x):
    """C round(): half away from zero."""
    return int(math.floor(x + 0.5)) if x >= 0 else -int(math.floor(-x + 0.5))


def fmt_float(v, decimals):
    """GRBL printFloat(): sign, then round half up at `decimals`."""
    if abs(v) < 1e-9:
        v = 0.0
    neg = v < 0
    k = int(abs(v) * 10 ** decimals + 0.5)
    if decimals:
        s = "%d.%0*d" % (k // 10 ** decimals, decimals, k % 10 ** decimals)
    else:
        s = "%d" % k
    return ("-" + s) if neg else s


def read_float(line, i):
    """nuts_bolts.c read_float(): returns (ok, value, next index)."""
    n = len(line)
    j = i
    neg = False
    if j < n and line[j] == "-":
        neg = True
        j += 1
    elif j < n and line[j] == "+":
        j += 1
    intval = 0
    exp = 0
    ndigit = 0
    isdecimal = False
    while j < n:
        c = line[j]
        if "0" <= c <= "9":
            ndigit += 1
            if ndigit <= MAX_INT_DIGITS:
                if isdecimal:
                    exp -= 1
                intval = intval * 10 + (ord(c) - 48)
            elif not isdecimal:
                exp += 1
        elif c == "." and not isdecimal:
            isdecimal = True
        else:
            break
        j += 1
    if not ndigit:
        return False, 0.0, j
    v = float(intval) * (10.0 ** exp) if intval else 0.0
    return True, (-v if neg else v), j


class Modal:
    __slots__ = ("motion", "feed_mode", "units", "distance", "plane", "coord_select",
                 "program_flow", "spindle", "coolant", "tool_length")

    def __init__(self):
        self.motion = MOTION_SEEK
        self.feed_mode = 0      # 0 = G94, 1 = G93
        self.units = 0          # 0 = G21, 1 = G20
        self.distance = 0       # 0 = G90, 1 = G91
        self.plane = 0          # 0 = G17, 1 = G18, 2 = G19
        self.coord_select = 0   # G54..G59 -> 0..5
        self.program_flow = FLOW_RUNNING
        self.spindle = SPINDLE_DISABLE
        self.coolant = 0
        self.tool_length = 0    # 0 = G49, 1 = G43.1

    def copy(self):
        m = Modal()
        for k in self.__slots__:
            setattr(m, k, getattr(self, k))
        return m


class PlanData:
    __slots__ = ("feed_rate", "spindle_speed", "rapid", "system", "no_feed_override",
                 "inverse_time", "spindle", "coolant", "jog", "approach")

    def __init__(self):
        self.feed_rate = 0.0
        self.spindle_speed = 0.0
        self.rapid = False
        self.system = False
        self.no_feed_override = False
        self.inverse_time = False
        self.spindle = SPINDLE_DISABLE
        self.coolant = 0
        self.jog = False
        self.approach = False


class Block:
    __slots__ = ("start", "target", "unit", "mm", "rate", "rapid", "system", "no_ovr",
                 "accel", "rapid_rate", "junction", "spindle", "spindle_speed", "approach")


class Emulator:
    def __init__(self, args):
        self.args = args
        self.scale = args.time_scale
        self.negative_space = args.negative_space
        self.force_set_origin = not args.negative_space
        self.defaults = default_settings(args.negative_space, not args.no_homing)
        self.settings = dict(self.defaults)
        for n, v in args.preset:
            self.settings[n] = v
        self.startup_lines = ["", ""]
        self.build_info = ""
        self.coord_data = [[0.0] * N_AXIS for _ in range(8)]  # G54..G59, G28, G30
        # machine
        self.sys_pos = [0.0] * N_AXIS
        self.probe_pos = [0.0] * N_AXIS
        self.probe_succeeded = False
        # physical X carriage: distance coordinate with the switch at 0
        self.switch_side = 1 if args.negative_space else -1
        self.phys_x = -self.switch_side * args.home_distance
        # stepper / planner
        self.planner = []
        self.pl_position = [0] * N_AXIS  # steps
        self.pl_prev_unit = [0.0] * N_AXIS
        self.st_running = False
        self.v = 0.0            # mm/s
        self.cur_done = 0.0     # mm done in planner[0]
        self.homing_axislock = False
        self.sim_last = None
        # system
        self.state = STATE_ALARM if self.homing_enabled() else STATE_IDLE
        self.reset_sys()
        self.rx = bytearray()
        self.rx_eol_numbers = []
        self.gc_init()
        # io
        self.master = None
        self.connected = False
        self.tx = bytearray()
        # --silent-after 0: a controller that never answers at all.
        self.silent = args.silent_after == 0
        self.raw_line = bytearray()
        self.last_eol = 0
        self.lines_received = 0
        self.logf = open(args.log, "a", encoding="utf-8") if args.log else None
        self.fast_wait = False
        self.running = True
        self.rx_dropped = 0
        self.wire = bytearray()
        self.wire_t0 = 0.0
        self.byte_rate = args.baud / 10.0  # 8N1: 10 bits per byte

    # ------------------------------------------------------------------ settings
    def s(self, n):
        return self.settings[n]

    def homing_enabled(self):
        return bool(int(self.settings[22]))

    def soft_limits_enabled(self):
        return bool(int(self.settings[20]))

    def laser_mode(self):
        return bool(int(self.settings[32]))

    def spm(self, i):
        return self.settings[100 + i]

    def reset_sys(self):
        self.suspend = 0
        self.step_control = 0
        self.abort = False
        self.soft_limit = False
        self.f_override = 100
        self.r_override = 100
        self.s_override = 100
        self.spindle_speed = 0.0
        self.spindle_on = SPINDLE_DISABLE
        self.coolant_on = 0
        self.report_wco_counter = 0
        self.report_ovr_counter = 0
        self.rt_state = 0
        self.rt_alarm = 0
        self.rt_motion_ovr = []
        self.rt_accessory_ovr = []
        self.probe_active = False
        self.laser_hold_off = False

    def gc_init(self):
        self.modal = Modal()
        self.gc_feed_rate = 0.0
        self.gc_spindle_speed = 0.0
        self.gc_tool = 0
        self.gc_position = [0.0] * N_AXIS
        self.coord_system = list(self.coord_data[0])
        self.coord_offset = [0.0] * N_AXIS
        self.tool_length_offset = 0.0

    # ------------------------------------------------------------------ output
    def out(self, data):
        if isinstance(data, str):
            data = data.encode("latin-1")
        if self.silent:
            return
        if len(self.tx) > (1 << 20):
            return  # nobody reads; drop
        self.tx += data
        if self.args.verbose:
            sys.stderr.write("<< %r\n" % data)

    def report_status_message(self, code, line_no):
        drop = line_no is not None and line_no in self.args.drop_ok
        if not drop:
            self.out("ok\r\n" if code == OK else "error:%d\r\n" % code)
        elif self.args.verbose:
            sys.stderr.write("-- dropped answer to line %d\n" % line_no)
        if line_no is not None:
            if line_no in self.args.garbage_after:
                self.out(GARBAGE_LINE)
            if self.args.silent_after is not None and line_no >= self.args.silent_after:
                self.silent = True

    def msg(self, text):
        self.out("[MSG:%s]\r\n" % text)

    # ------------------------------------------------------------------ time
    def sim_now(self):
        return time.monotonic() / self.scale if self.scale > 0 else time.monotonic() * 1e9

    def delay(self, seconds):
        """Plain delay (delay_ms): no real-time processing."""
        end = self.sim_now() + seconds
        while self.sim_now() < end:
            self.fast_wait = True
            yield

    # ------------------------------------------------------------------ ISR
    def log_line(self, text):
        if self.logf:
            self.logf.write(text + "\n")
            self.logf.flush()

    def isr_rx(self, b):
        if b == CMD_RESET:
            self.log_rt("<0x18>")
            self.mc_reset()
            return
        if b == CMD_STATUS:
            self.log_rt("<?>")
            self.rt_state |= EXEC_STATUS_REPORT
            return
        if b == CMD_CYCLE_START:
            self.log_rt("<~>")
            self.rt_state |= EXEC_CYCLE_START
            return
        if b == CMD_FEED_HOLD:
            self.log_rt("<!>")
            self.rt_state |= EXEC_FEED_HOLD
            return
        if b > 0x7F:
            self.log_rt("<0x%02x>" % b)
            if b == CMD_JOG_CANCEL:
                if self.state & STATE_JOG:
                    self.rt_state |= EXEC_MOTION_CANCEL
            elif 0x90 <= b <= 0x97:
                self.rt_motion_ovr.append(b)
            elif 0x99 <= b <= 0x9D or b == 0xA0:
                self.rt_accessory_ovr.append(b)
            return  # others (0x84 door, 0x9E, unknown) ignored
        # an ordinary character: line bookkeeping for log / faults
        line_no = None
        if b in (10, 13):
            if self.args.merge_crlf and b == 10 and self.last_eol == 13:
                self.last_eol = 0
                return  # second half of a CRLF: not a line of its own
            self.last_eol = b
            self.lines_received += 1
            line_no = self.lines_received
            text = self.raw_line.decode("latin-1").strip()
            self.raw_line = bytearray()
            self.log_line(text)
            if self.args.verbose:
                sys.stderr.write(">> line %d: %r\n" % (line_no, text))
            if self.args.vanish_after is not None and line_no >= self.args.vanish_after:
                self.vanish()
                return
        else:
            self.last_eol = 0
            self.raw_line.append(b)
        if len(self.rx) < RX_BUFFER_SIZE:
            self.rx.append(b)
            if line_no is not None:
                self.rx_eol_numbers.append(line_no)
        else:
            self.rx_dropped += 1
            if self.args.verbose:
                sys.stderr.write("-- RX buffer full, byte 0x%02x lost\n" % b)

    def log_rt(self, text):
        if self.args.log_realtime:
            self.log_line(text)

    def mc_reset(self):
        if not (self.rt_state & EXEC_RESET):
            self.rt_state |= EXEC_RESET
            self.spindle_stop()
            self.coolant_on = 0
            if (self.state & (STATE_CYCLE | STATE_HOMING | STATE_JOG)) or \
                    (self.step_control & (STEP_CONTROL_EXECUTE_HOLD | STEP_CONTROL_EXECUTE_SYS_MOTION)):
                if self.state == STATE_HOMING:
                    if not self.rt_alarm:
                        self.rt_alarm = ALARM_HOMING_FAIL_RESET
                else:
                    self.rt_alarm = ALARM_ABORT_CYCLE
                self.st_go_idle()

    # ------------------------------------------------------------------ spindle / coolant
    def spindle_stop(self):
        self.spindle_on = SPINDLE_DISABLE
        self.spindle_speed = 0.0

    def compute_spindle_speed(self, rpm):
        rpm *= 0.01 * self.s_override
        rmax, rmin = self.s(30), self.s(31)
        if rmin >= rmax or rpm >= rmax:
            return rmax
        if rpm <= rmin:
            return 0.0 if rpm == 0.0 else rmin
        return rpm

    def spindle_set_state(self, state, rpm):
        if self.abort:
            return
        if state == SPINDLE_DISABLE:
            self.spindle_stop()
        else:
            if self.laser_mode() and state == SPINDLE_CCW:
                rpm = 0.0
            self.spindle_on = state
            self.spindle_speed = self.compute_spindle_speed(rpm)
        self.report_ovr_counter = 0

    def spindle_sync(self, state, rpm):
        if self.state == STATE_CHECK_MODE:
            return
        yield from self.buffer_synchronize()
        self.spindle_set_state(state, rpm)

    def coolant_sync(self, mode):
        if self.state == STATE_CHECK_MODE:
            return
        yield from self.buffer_synchronize()
        if not self.abort:
            self.coolant_on = mode
            self.report_ovr_counter = 0

    # ------------------------------------------------------------------ limits
    def switch_pressed(self, strict):
        p = self.phys_x * self.switch_side
        return p > 0 if strict else p >= -1e-9

    def check_travel_limits(self, target):
        for i in range(N_AXIS):
            travel = self.s(130 + i)
            if self.force_set_origin:
                if int(self.s(23)) & (1 << i):
                    if target[i] < 0 or target[i] > travel:
                        return True
                else:
                    if target[i] > 0 or target[i] < -travel:
                        return True
            else:
                if target[i] > 0 or target[i] < -travel:
                    return True
        return False

    def limits_soft_check(self, target):
        if self.check_travel_limits(target):
            self.soft_limit = True
            if self.state == STATE_CYCLE:
                self.rt_state |= EXEC_FEED_HOLD
                while True:
                    yield from self.rt()
                    if self.abort:
                        return
                    if self.state == STATE_IDLE:
                        break
                    yield
            self.mc_reset()
            self.rt_alarm = ALARM_SOFT_LIMIT
            yield from self.rt()

    # ------------------------------------------------------------------ planner
    @staticmethod
    def limit_by_axis_max(values, unit):
        lim = float("inf")
        for i in range(N_AXIS):
            if unit[i] != 0:
                lim = min(lim, abs(values[i] / unit[i]))
        return lim

    def plan_buffer_line(self, target, pl):
        spm = [self.spm(i) for i in range(N_AXIS)]
        if pl.system:
            pos_steps = [c_round(self.sys_pos[i] * spm[i]) for i in range(N_AXIS)]
        else:
            pos_steps = list(self.pl_position)
        target_steps = [c_round(target[i] * spm[i]) for i in range(N_AXIS)]
        delta = [target_steps[i] - pos_steps[i] for i in range(N_AXIS)]
        if not any(delta):
            return False
        delta_mm = [delta[i] / spm[i] for i in range(N_AXIS)]
        mm = math.sqrt(sum(d * d for d in delta_mm))
        unit = [d / mm for d in delta_mm]
        b = Block()
        b.start = [pos_steps[i] / spm[i] for i in range(N_AXIS)]
        if pl.system:
            b.start = list(self.sys_pos)
        b.target = [target_steps[i] / spm[i] for i in range(N_AXIS)]
        b.unit = unit
        b.mm = math.sqrt(sum((b.target[i] - b.start[i]) ** 2 for i in range(N_AXIS))) or mm
        b.accel = self.limit_by_axis_max([self.s(120 + i) for i in range(N_AXIS)], unit)
        b.rapid_rate = self.limit_by_axis_max([self.s(110 + i) for i in range(N_AXIS)], unit)
        b.rapid = pl.rapid
        b.system = pl.system
        b.no_ovr = pl.no_feed_override
        b.approach = pl.approach
        if pl.rapid:
            b.rate = b.rapid_rate
        else:
            b.rate = pl.feed_rate * mm if pl.inverse_time else pl.feed_rate
        b.spindle = pl.spindle
        b.spindle_speed = pl.spindle_speed
        if not self.planner or pl.system:
            b.junction = 0.0
        else:
            prev = self.pl_prev_unit
            cos_theta = -sum(prev[i] * unit[i] for i in range(N_AXIS))
            if cos_theta > 0.999999:
                b.junction = 0.0
            elif cos_theta < -0.999999:
                b.junction = 1e38
            else:
                ju = [unit[i] - prev[i] for i in range(N_AXIS)]
                n = math.sqrt(sum(x * x for x in ju))
                ju = [x / n for x in ju]
                jacc = self.limit_by_axis_max([self.s(120 + i) for i in range(N_AXIS)], ju)
                sin_d2 = math.sqrt(0.5 * (1.0 - cos_theta))
                v2 = (jacc * self.s(11) * sin_d2) / (1.0 - sin_d2)
                b.junction = math.sqrt(max(0.0, v2))
        self.planner.append(b)
        if not pl.system:
            self.pl_position = target_steps
            self.pl_prev_unit = unit
        return True

    def plan_sync_position(self):
        self.pl_position = [c_round(self.sys_pos[i] * self.spm(i)) for i in range(N_AXIS)]

    def gc_sync_position(self):
        self.gc_position = list(self.sys_pos)

    def plan_reset(self):
        self.planner = []
        self.cur_done = 0.0

    def nominal_speed(self, b):
        """mm/s (plan_compute_profile_nominal_speed)."""
        v = b.rate
        if b.rapid:
            v *= 0.01 * self.r_override
        else:
            if not b.no_ovr:
                v *= 0.01 * self.f_override
            v = min(v, b.rapid_rate)
        return max(v, MINIMUM_FEED_RATE) / 60.0

    def exit_speed_of_current(self):
        q = self.planner
        ex = 0.0
        for i in range(len(q) - 1, 0, -1):
            b = q[i]
            maxentry = min(b.junction, self.nominal_speed(b), self.nominal_speed(q[i - 1]))
            ex = min(maxentry, math.sqrt(ex * ex + 2.0 * b.accel * b.mm))
        return ex

    # ------------------------------------------------------------------ stepper
    def st_wake_up(self):
        if self.planner:
            self.st_running = True

    def st_go_idle(self):
        self.st_running = False
        self.v = 0.0
        self.snap_position()

    def st_reset(self):
        self.st_running = False
        self.v = 0.0
        self.cur_done = 0.0

    def snap_position(self):
        for i in range(N_AXIS):
            spm = self.spm(i)
            self.sys_pos[i] = c_round(self.sys_pos[i] * spm) / spm

    def set_pos_along(self, b, done):
        old_x = self.sys_pos[0]
        for i in range(N_AXIS):
            self.sys_pos[i] = b.start[i] + b.unit[i] * done
        self.phys_x += self.sys_pos[0] - old_x

    def stepper_tick(self):
        now = self.sim_now()
        last = self.sim_last
        self.sim_last = now
        if last is None or not self.st_running:
            return
        dt_total = min(now - last, 30.0)
        while dt_total > 0 and self.st_running and self.planner:
            dt = min(dt_total, SIM_STEP)
            dt_total -= dt
            self.st_substep(dt)

    def st_substep(self, dt):
        """Advance dt seconds. Returns True when the block changed."""
        b = self.planner[0]
        a = b.accel
        rem = b.mm - self.cur_done
        v = self.v
        holding = bool(self.step_control & STEP_CONTROL_EXECUTE_HOLD)
        if holding:
            v_new = max(0.0, v - a * dt)
        else:
            vnom = self.nominal_speed(b)
            ex = self.exit_speed_of_current() if len(self.planner) > 1 else 0.0
            v_lim = min(vnom, math.sqrt(ex * ex + 2.0 * a * max(rem, 0.0)))
            if v < v_lim:
                v_new = min(v + a * dt, v_lim)
            else:
                v_new = max(v - a * dt, v_lim)
        ds = 0.5 * (v + v_new) * dt
        self.v = v_new
        changed = False
        if holding and v_new <= 0.0:
            # hold complete: stop where we are
            self.cur_done = min(b.mm, self.cur_done + ds)
            self.set_pos_along(b, self.cur_done)
            self.st_running = False
            self.v = 0.0
            self.rt_state |= EXEC_CYCLE_STOP
            self.laser_update(None)
            return False
        if ds >= rem or rem <= 1e-9:
            self.cur_done = b.mm
            self.set_pos_along(b, b.mm)
            for i in range(N_AXIS):
                self.sys_pos[i] = b.target[i]
            self.after_move(b)
            if not self.st_running:
                return True
            self.planner.pop(0)
            self.cur_done = 0.0
            changed = True
            if not self.planner:
                self.st_running = False
                self.v = 0.0
                self.rt_state |= EXEC_CYCLE_STOP
                self.laser_update(None)
                return True
            self.laser_update(self.planner[0])
        else:
            self.cur_done += ds
            self.set_pos_along(b, self.cur_done)
            self.after_move(b)
            self.laser_update(b)
        return changed

    def after_move(self, b):
        """Limit switch checks after the carriage moved."""
        if b.approach:
            if self.homing_axislock and self.switch_pressed(False):
                over = self.phys_x
                self.phys_x = 0.0
                self.sys_pos[0] -= over
                self.homing_axislock = False
                self.st_running = False
                self.v = 0.0
            return
        if b.system:
            return
        if int(self.s(21)) and self.switch_pressed(True) and not self.rt_alarm:
            # hard limit ISR: mc_reset(); system_set_exec_alarm(EXEC_ALARM_HARD_LIMIT)
            self.mc_reset()
            self.rt_alarm = ALARM_HARD_LIMIT

    def laser_update(self, b):
        if not self.laser_mode() or self.spindle_on == SPINDLE_DISABLE:
            return
        if b is None:
            if self.spindle_on == SPINDLE_CCW:
                self.spindle_speed = 0.0
            return
        rpm = b.spindle_speed
        if b.spindle == SPINDLE_CCW:
            vnom = self.nominal_speed(b)
            rpm *= (self.v / vnom) if vnom > 0 else 0.0
        self.spindle_speed = self.compute_spindle_speed(rpm) if rpm > 0 else 0.0

    # ------------------------------------------------------------------ reports
    def report_status(self):
        st = self.state
        if st == STATE_IDLE:
            name = "Idle"
        elif st & STATE_CYCLE:
            name = "Run"
        elif st & STATE_HOLD and not (self.suspend & SUSPEND_JOG_CANCEL):
            name = "Hold:0" if self.suspend & SUSPEND_HOLD_COMPLETE else "Hold:1"
        elif st & (STATE_JOG | STATE_HOLD):
            name = "Jog"
        elif st & STATE_HOMING:
            name = "Home"
        elif st & STATE_ALARM:
            name = "Alarm"
        elif st & STATE_CHECK_MODE:
            name = "Check"
        elif st & STATE_SLEEP:
            name = "Sleep"
        else:
            name = "Door:0"
        pos = [c_round(self.sys_pos[i] * self.spm(i)) / self.spm(i) for i in range(N_AXIS)]
        wco = [self.coord_system[i] + self.coord_offset[i] for i in range(N_AXIS)]
        wco[2] += self.tool_length_offset
        mask = int(self.s(10))
        inches = bool(int(self.s(13)))
        if not (mask & 1):
            pos = [pos[i] - wco[i] for i in range(N_AXIS)]

        def coords(vals):
            if inches:
                return ",".join(fmt_float(v / MM_PER_INCH, 4) for v in vals)
            return ",".join(fmt_float(v, 3) for v in vals)

        parts = ["<", name, "|MPos:" if mask & 1 else "|WPos:", coords(pos)]
        if mask & 2:
            parts.append("|Bf:%d,%d" % (BLOCK_BUFFER_SLOTS - len(self.planner),
                                        RX_BUFFER_SIZE - len(self.rx)))
        moving = st & (STATE_CYCLE | STATE_HOMING | STATE_HOLD | STATE_JOG | STATE_SAFETY_DOOR)
        rate = self.v * 60.0 if moving else 0.0
        rate_s = fmt_float(rate / MM_PER_INCH, 1) if inches else fmt_float(rate, 0)
        parts.append("|FS:%s,%s" % (rate_s, fmt_float(self.spindle_speed, 0)))
        if self.switch_pressed(True):
            parts.append("|Pn:X")
        busy = bool(st & (STATE_HOMING | STATE_CYCLE | STATE_HOLD | STATE_JOG | STATE_SAFETY_DOOR))
        if self.report_wco_counter > 0:
            self.report_wco_counter -= 1
        else:
            self.report_wco_counter = (30 if busy else 10) - 1
            if self.report_ovr_counter == 0:
                self.report_ovr_counter = 1
            if not self.args.plain_status:
                parts.append("|WCO:" + coords(wco))
        if self.report_ovr_counter > 0:
            self.report_ovr_counter -= 1
        else:
            self.report_ovr_counter = (20 if busy else 10) - 1
            if not self.args.plain_status:
                parts.append("|Ov:%d,%d,%d" % (self.f_override, self.r_override, self.s_override))
                acc = ""
                if self.spindle_on != SPINDLE_DISABLE and self.spindle_speed > 0:
                    acc += "S" if self.spindle_on == SPINDLE_CW else "C"
                if self.coolant_on & COOLANT_FLOOD:
                    acc += "F"
                if acc:
                    parts.append("|A:" + acc)
        parts.append(">\r\n")
        self.out("".join(parts))

    def report_settings(self):
        lines = []
        for n in SETTING_ORDER:
            v = self.settings[n]
            kind = SETTING_KINDS[n]
            if kind == "u":
                lines.append("$%d=%d\r\n" % (n, int(v)))
            elif kind == "r":
                lines.append("$%d=%s\r\n" % (n, fmt_float(v, 0)))
            else:
                lines.append("$%d=%s\r\n" % (n, fmt_float(v, 3)))
        self.out("".join(lines))

    def report_gcode_modes(self):
        m = self.modal
        if m.motion >= MOTION_PROBE_TOWARD:
            motion = "38.%d" % (m.motion - (MOTION_PROBE_TOWARD - 2))
        else:
            motion = "%d" % m.motion
        s = "[GC:G%s G%d G%d G%d G%d G%d" % (motion, m.coord_select + 54, m.plane + 17,
                                             21 - m.units, m.distance + 90, 94 - m.feed_mode)
        if m.program_flow:
            s += " M%d" % (0 if m.program_flow == FLOW_PAUSED else m.program_flow)
        s += {SPINDLE_CW: " M3", SPINDLE_CCW: " M4"}.get(m.spindle, " M5")
        s += " M8" if m.coolant else " M9"
        s += " T%d" % self.gc_tool
        if int(self.s(13)):
            s += " F" + fmt_float(self.gc_feed_rate / MM_PER_INCH, 1)
        else:
            s += " F" + fmt_float(self.gc_feed_rate, 0)
        s += " S" + fmt_float(self.gc_spindle_speed, 0)
        self.out(s + "]\r\n")

    def coord_str(self, vals):
        if int(self.s(13)):
            return ",".join(fmt_float(v / MM_PER_INCH, 4) for v in vals)
        return ",".join(fmt_float(v, 3) for v in vals)

    def report_probe(self):
        self.out("[PRB:%s:%d]\r\n" % (self.coord_str(self.probe_pos), 1 if self.probe_succeeded else 0))

    def report_ngc(self):
        for i in range(8):
            name = {6: "28", 7: "30"}.get(i, "%d" % (54 + i))
            self.out("[G%s:%s]\r\n" % (name, self.coord_str(self.coord_data[i])))
        self.out("[G92:%s]\r\n" % self.coord_str(self.coord_offset))
        tlo = self.tool_length_offset / MM_PER_INCH if int(self.s(13)) else self.tool_length_offset
        self.out("[TLO:%s]\r\n" % fmt_float(tlo, 4 if int(self.s(13)) else 3))
        self.report_probe()

    def report_build_info(self):
        self.out("[VER:%s.%s:%s]\r\n" % (GRBL_VERSION, GRBL_VERSION_BUILD, self.build_info))
        self.out("[OPT:V%s,%d,%d]\r\n" % ("Z" if self.force_set_origin else "",
                                          BLOCK_BUFFER_SLOTS, RX_BUFFER_SIZE))

    # ------------------------------------------------------------------ protocol (main program)
    def rt(self):
        """protocol_execute_realtime()"""
        yield from self.exec_rt_system()
        if self.suspend:
            yield from self.exec_rt_suspend()

    def exec_rt_system(self):
        alarm = self.rt_alarm
        if alarm:
            self.state = STATE_ALARM
            self.out("ALARM:%d\r\n" % alarm)
            yield from self.delay(0.5)
            if alarm in (ALARM_HARD_LIMIT, ALARM_SOFT_LIMIT):
                self.msg("Reset to continue")
                self.rt_state &= ~EXEC_RESET
                while not (self.rt_state & EXEC_RESET):
                    yield
            self.rt_alarm = 0
        st = self.rt_state
        if st:
            if st & EXEC_RESET:
                self.abort = True
                return
            if st & EXEC_STATUS_REPORT:
                self.report_status()
                self.rt_state &= ~EXEC_STATUS_REPORT
            if st & (EXEC_MOTION_CANCEL | EXEC_FEED_HOLD | EXEC_SLEEP):
                if not (self.state & (STATE_ALARM | STATE_CHECK_MODE)):
                    if self.state & (STATE_CYCLE | STATE_JOG):
                        if not (self.suspend & (SUSPEND_MOTION_CANCEL | SUSPEND_JOG_CANCEL)):
                            self.step_control = STEP_CONTROL_EXECUTE_HOLD
                            if self.state == STATE_JOG and not (st & EXEC_SLEEP):
                                self.suspend |= SUSPEND_JOG_CANCEL
                    if self.state == STATE_IDLE:
                        self.suspend = SUSPEND_HOLD_COMPLETE
                    if st & EXEC_MOTION_CANCEL and not (self.state & STATE_JOG):
                        self.suspend |= SUSPEND_MOTION_CANCEL
                    if st & EXEC_FEED_HOLD:
                        if not (self.state & (STATE_SAFETY_DOOR | STATE_JOG | STATE_SLEEP)):
                            self.state = STATE_HOLD
                if st & EXEC_SLEEP:
                    if self.state == STATE_ALARM:
                        self.suspend |= SUSPEND_RETRACT_COMPLETE | SUSPEND_HOLD_COMPLETE
                    self.state = STATE_SLEEP
                self.rt_state &= ~(EXEC_MOTION_CANCEL | EXEC_FEED_HOLD | EXEC_SLEEP)
            if st & EXEC_CYCLE_START:
                if not (st & (EXEC_FEED_HOLD | EXEC_MOTION_CANCEL | EXEC_SAFETY_DOOR)):
                    if self.state == STATE_IDLE or \
                            (self.state & STATE_HOLD and self.suspend & SUSPEND_HOLD_COMPLETE):
                        self.step_control = 0
                        if self.laser_hold_off:
                            self.laser_hold_off = False
                            self.spindle_speed = self.laser_saved_speed
                        if self.planner and not (self.suspend & SUSPEND_MOTION_CANCEL):
                            self.suspend = 0
                            self.state = STATE_CYCLE
                            self.st_wake_up()
                        else:
                            self.suspend = 0
                            self.state = STATE_IDLE
                self.rt_state &= ~EXEC_CYCLE_START
            if st & EXEC_CYCLE_STOP:
                if (self.state & (STATE_HOLD | STATE_SAFETY_DOOR | STATE_SLEEP)) and \
                        not self.soft_limit and not (self.suspend & SUSPEND_JOG_CANCEL):
                    if self.step_control & STEP_CONTROL_EXECUTE_HOLD:
                        self.suspend |= SUSPEND_HOLD_COMPLETE
                    self.step_control &= ~(STEP_CONTROL_EXECUTE_HOLD | STEP_CONTROL_EXECUTE_SYS_MOTION)
                else:
                    if self.suspend & SUSPEND_JOG_CANCEL:
                        self.step_control = 0
                        self.plan_reset()
                        self.st_reset()
                        self.snap_position()
                        self.gc_sync_position()
                        self.plan_sync_position()
                    self.suspend = 0
                    self.state = STATE_IDLE
                self.rt_state &= ~EXEC_CYCLE_STOP
        # overrides
        if self.rt_motion_ovr:
            cmds, self.rt_motion_ovr = self.rt_motion_ovr, []
            f, r = self.f_override, self.r_override
            for c in cmds:
                if c == 0x90:
                    f = 100
                elif c == 0x91:
                    f += 10
                elif c == 0x92:
                    f -= 10
                elif c == 0x93:
                    f += 1
                elif c == 0x94:
                    f -= 1
                elif c == 0x95:
                    r = 100
                elif c == 0x96:
                    r = 50
                elif c == 0x97:
                    r = 25
            f = max(10, min(200, f))
            if f != self.f_override or r != self.r_override:
                self.f_override, self.r_override = f, r
                self.report_ovr_counter = 0
        if self.rt_accessory_ovr:
            cmds, self.rt_accessory_ovr = self.rt_accessory_ovr, []
            s = self.s_override
            toggle_flood = False
            for c in cmds:
                if c == 0x99:
                    s = 100
                elif c == 0x9A:
                    s += 10
                elif c == 0x9B:
                    s -= 10
                elif c == 0x9C:
                    s += 1
                elif c == 0x9D:
                    s -= 1
                elif c == 0xA0:
                    toggle_flood = not toggle_flood
            s = max(10, min(200, s))
            if s != self.s_override:
                self.s_override = s
                if self.spindle_on != SPINDLE_DISABLE and not self.laser_mode():
                    self.spindle_speed = self.compute_spindle_speed(self.gc_spindle_speed)
                self.report_ovr_counter = 0
            if toggle_flood and ((self.state == STATE_IDLE) or
                                 (self.state & (STATE_CYCLE | STATE_HOLD | STATE_JOG))):
                self.modal.coolant ^= COOLANT_FLOOD
                self.coolant_on = self.modal.coolant
                self.report_ovr_counter = 0

    def exec_rt_suspend(self):
        while self.suspend:
            if self.abort:
                return
            if self.suspend & SUSPEND_HOLD_COMPLETE:
                if self.state & STATE_SLEEP:
                    self.msg("Sleeping")
                    self.spindle_set_state(SPINDLE_DISABLE, 0.0)
                    self.coolant_on = 0
                    self.st_go_idle()
                    while not self.abort:
                        yield from self.exec_rt_system()
                        yield
                    return
                if self.state == STATE_HOLD and self.laser_mode() and \
                        self.spindle_on != SPINDLE_DISABLE and not self.laser_hold_off:
                    # DISABLE_LASER_DURING_HOLD
                    self.laser_hold_off = True
                    self.laser_saved_speed = self.spindle_speed
                    self.spindle_speed = 0.0
                    self.report_ovr_counter = 0
            yield from self.exec_rt_system()
            yield

    def auto_cycle_start(self):
        if self.planner:
            self.rt_state |= EXEC_CYCLE_START

    def buffer_synchronize(self):
        self.auto_cycle_start()
        while True:
            yield from self.rt()
            if self.abort:
                return
            if not (self.planner or self.state == STATE_CYCLE):
                return
            yield

    def firmware(self):
        """main(): the reset loop."""
        while True:
            prior = self.state
            self.reset_sys()
            self.state = prior
            self.rx = bytearray()
            self.rx_eol_numbers = []
            self.gc_init()
            self.plan_reset()
            self.st_reset()
            self.snap_position()
            self.plan_sync_position()
            self.gc_sync_position()
            self.out("\r\nGrbl %s ['$' for help]\r\n" % GRBL_VERSION)
            yield from self.protocol_main_loop()

    def protocol_main_loop(self):
        if int(self.s(21)) and self.switch_pressed(True):
            self.state = STATE_ALARM
            self.msg("Check Limits")
        if self.state & (STATE_ALARM | STATE_SLEEP):
            self.msg("'$H'|'$X' to unlock")
            self.state = STATE_ALARM
        else:
            self.state = STATE_IDLE
            yield from self.execute_startup()
        line = []
        flag_overflow = flag_paren = flag_semi = False
        while True:
            while self.rx:
                c = self.rx.pop(0)
                if c in (10, 13):
                    line_no = self.rx_eol_numbers.pop(0) if self.rx_eol_numbers else None
                    yield from self.rt()
                    if self.abort:
                        return
                    text = "".join(line)
                    if flag_overflow:
                        status = E_OVERFLOW
                    elif not text:
                        status = OK
                    elif text[0] == "$":
                        status = yield from self.system_execute_line(text)
                    elif self.state & (STATE_ALARM | STATE_JOG):
                        status = E_SYSTEM_GC_LOCK
                    else:
                        status = yield from self.gc_execute_line(text)
                    self.report_status_message(status, line_no)
                    line = []
                    flag_overflow = flag_paren = flag_semi = False
                    if self.abort:
                        return
                else:
                    ch = chr(c)
                    if flag_overflow or flag_paren or flag_semi:
                        if ch == ")" and flag_paren:
                            flag_paren = False
                    elif c <= 32:
                        pass
                    elif ch == "/":
                        pass
                    elif ch == "(":
                        flag_paren = True
                    elif ch == ";":
                        flag_semi = True
                    elif len(line) >= LINE_BUFFER_SIZE - 1:
                        flag_overflow = True
                    elif "a" <= ch <= "z":
                        line.append(ch.upper())
                    else:
                        line.append(ch)
            self.auto_cycle_start()
            yield from self.rt()
            if self.abort:
                return
            yield

    def execute_startup(self):
        for n in range(2):
            text = self.startup_lines[n]
            if text:
                status = yield from self.gc_execute_line(text)
                self.out(">%s:" % text)
                self.out("ok\r\n" if status == OK else "error:%d\r\n" % status)

    # ------------------------------------------------------------------ $ commands
    def system_execute_line(self, line):
        c1 = line[1] if len(line) > 1 else ""
        c2 = line[2] if len(line) > 2 else ""
        if c1 == "":
            self.out("[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]\r\n")
            return OK
        if c1 == "J":
            if self.state != STATE_IDLE and self.state != STATE_JOG:
                return E_IDLE_ERROR
            if c2 != "=":
                return E_INVALID_STATEMENT
            status = yield from self.gc_execute_line(line)
            return status
        if c1 in "$GCX":
            if c2 != "":
                return E_INVALID_STATEMENT
            if c1 == "$":
                if self.state & (STATE_CYCLE | STATE_HOLD):
                    return E_IDLE_ERROR
                self.report_settings()
            elif c1 == "G":
                self.report_gcode_modes()
            elif c1 == "C":
                if self.state == STATE_CHECK_MODE:
                    self.mc_reset()
                    self.msg("Disabled")
                else:
                    if self.state:
                        return E_IDLE_ERROR
                    self.state = STATE_CHECK_MODE
                    self.msg("Enabled")
            elif c1 == "X":
                if self.state == STATE_ALARM:
                    self.msg("Caution: Unlocked")
                    self.state = STATE_IDLE
            return OK
        if not (self.state == STATE_IDLE or self.state == STATE_ALARM):
            return E_IDLE_ERROR
        if c1 == "#":
            if c2 != "":
                return E_INVALID_STATEMENT
            self.report_ngc()
            return OK
        if c1 == "H":
            if not self.homing_enabled():
                return E_SETTING_DISABLED
            if c2 != "":
                return E_INVALID_STATEMENT
            self.state = STATE_HOMING
            yield from self.mc_homing_cycle()
            if not self.abort:
                self.state = STATE_IDLE
                yield from self.execute_startup()
            return OK
        if c1 == "S":
            if line != "$SLP":
                return E_INVALID_STATEMENT
            self.rt_state |= EXEC_SLEEP
            return OK
        if c1 == "I":
            if c2 == "":
                self.report_build_info()
                return OK
            if c2 != "=":
                return E_INVALID_STATEMENT
            self.build_info = line[3:]
            return OK
        if c1 == "R":
            if not (line.startswith("$RST=") and len(line) == 6):
                return E_INVALID_STATEMENT
            what = line[5]
            if what == "$":
                self.settings = dict(self.defaults)
            elif what == "#":
                self.coord_data = [[0.0] * N_AXIS for _ in range(8)]
            elif what == "*":
                self.settings = dict(self.defaults)
                self.coord_data = [[0.0] * N_AXIS for _ in range(8)]
                self.startup_lines = ["", ""]
                self.build_info = ""
            else:
                return E_INVALID_STATEMENT
            self.msg("Restoring defaults")
            self.mc_reset()
            return OK
        store_startup = False
        idx = 1
        if c1 == "N":
            if c2 == "":
                for n in range(2):
                    self.out("$N%d=%s\r\n" % (n, self.startup_lines[n]))
                return OK
            if self.state != STATE_IDLE:
                return E_IDLE_ERROR
            store_startup = True
            idx = 2
        ok, parameter, idx = read_float(line, idx)
        if not ok:
            return E_BAD_NUMBER_FORMAT
        if idx >= len(line) or line[idx] != "=":
            return E_INVALID_STATEMENT
        idx += 1
        if store_startup:
            text = line[idx:]
            n = int(parameter)
            if n not in (0, 1):
                return E_INVALID_STATEMENT
            if len(text) >= LINE_BUFFER_SIZE - 1 - (idx - 1):
                return E_LINE_LENGTH_EXCEEDED
            status = yield from self.gc_execute_line(text)
            if status:
                return status
            self.startup_lines[n] = text
            return OK
        ok, value, idx = read_float(line, idx)
        if not ok:
            return E_BAD_NUMBER_FORMAT
        if idx != len(line) or parameter > 255:
            return E_INVALID_STATEMENT
        return self.store_setting(int(parameter), value)

    def store_setting(self, p, value):
        if value < 0.0:
            return E_NEGATIVE_VALUE
        if p >= 100:
            q = p - 100
            set_idx = 0
            while True:
                if q < N_AXIS:
                    break
                set_idx += 1
                if q < 10 or set_idx == 4:
                    return E_INVALID_STATEMENT
                q -= 10
            self.settings[100 + 10 * set_idx + q] = float(value)
            return OK
        iv = int(value) & 0xFF
        if p not in SETTING_KINDS:
            return E_INVALID_STATEMENT
        if p == 0 and iv < 3:
            return E_SETTING_STEP_PULSE_MIN
        if p == 20 and iv and not self.homing_enabled():
            return E_SOFT_LIMIT_ERROR
        if p == 22 and not iv:
            self.settings[20] = 0
        if SETTING_KINDS[p] == "u":
            if p in (4, 5, 6, 13, 20, 21, 22, 32):
                iv = 1 if iv else 0
            self.settings[p] = iv
        else:
            self.settings[p] = float(value)
        if p == 13:
            self.report_wco_counter = 0
        return OK

    # ------------------------------------------------------------------ homing
    def mc_homing_cycle(self):
        yield from self.limits_go_home(HOMING_CYCLE_MASK)
        yield from self.rt()
        if self.abort:
            return
        self.gc_sync_position()
        self.plan_sync_position()

    def limits_go_home(self, cycle_mask):
        if self.abort:
            return
        axes = [i for i in range(N_AXIS) if cycle_mask & (1 << i)]
        max_travel = max(HOMING_AXIS_SEARCH_SCALAR * self.s(130 + i) for i in axes)
        approach = True
        homing_rate = self.s(25)
        n_cycle = 2 * N_HOMING_LOCATE_CYCLE + 1
        dir_mask = int(self.s(23))
        while True:
            target = list(self.sys_pos)
            for i in axes:
                self.sys_pos[i] = 0.0
                if dir_mask & (1 << i):
                    target[i] = -max_travel if approach else max_travel
                else:
                    target[i] = max_travel if approach else -max_travel
            pl = PlanData()
            pl.system = True
            pl.no_feed_override = True
            pl.feed_rate = homing_rate * math.sqrt(len(axes))
            pl.approach = approach
            self.plan_reset()
            self.plan_buffer_line(target, pl)
            self.homing_axislock = True
            self.step_control = STEP_CONTROL_EXECUTE_SYS_MOTION
            self.cur_done = 0.0
            self.v = 0.0
            self.st_wake_up()
            while True:
                if self.rt_state & (EXEC_RESET | EXEC_CYCLE_STOP):
                    if self.rt_state & EXEC_RESET:
                        self.rt_alarm = ALARM_HOMING_FAIL_RESET
                    if not approach and self.switch_pressed(False):
                        self.rt_alarm = ALARM_HOMING_FAIL_PULLOFF
                    if approach and self.rt_state & EXEC_CYCLE_STOP:
                        self.rt_alarm = ALARM_HOMING_FAIL_APPROACH
                    if self.rt_alarm:
                        self.mc_reset()
                        self.st_go_idle()
                        yield from self.rt()
                        return
                    self.rt_state &= ~EXEC_CYCLE_STOP
                    break
                if approach and not self.homing_axislock:
                    break
                self.fast_wait = True
                yield
            self.st_reset()
            self.plan_reset()
            yield from self.delay(self.s(26) / 1000.0)
            approach = not approach
            if approach:
                max_travel = self.s(27) * HOMING_AXIS_LOCATE_SCALAR
                homing_rate = self.s(24)
            else:
                max_travel = self.s(27)
                homing_rate = self.s(25)
            if n_cycle <= 0:
                break
            n_cycle -= 1
        for i in axes:
            if self.force_set_origin:
                pos = 0.0
            elif dir_mask & (1 << i):
                pos = -self.s(130 + i) + self.s(27)
            else:
                pos = -self.s(27)
            self.sys_pos[i] = c_round(pos * self.spm(i)) / self.spm(i)
        self.step_control = 0

    # ------------------------------------------------------------------ motion control
    def mc_line(self, target, pl):
        if self.soft_limits_enabled() and self.state != STATE_JOG:
            yield from self.limits_soft_check(target)
        if self.state == STATE_CHECK_MODE:
            return
        while True:
            yield from self.rt()
            if self.abort:
                return
            if len(self.planner) >= BLOCK_BUFFER_SLOTS:
                self.auto_cycle_start()
                yield
            else:
                break
        queued = self.plan_buffer_line(target, pl)
        if not queued and self.laser_mode() and pl.spindle == SPINDLE_CW:
            yield from self.spindle_sync(SPINDLE_CW, pl.spindle_speed)

    def mc_dwell(self, seconds):
        if self.state == STATE_CHECK_MODE:
            return
        yield from self.buffer_synchronize()
        remaining = seconds
        last = self.sim_now()
        while remaining > 0:
            if self.abort:
                return
            now = self.sim_now()
            remaining -= now - last
            yield from self.rt()
            last = self.sim_now()  # time spent suspended does not count
            if remaining <= 0 or self.abort:
                break
            self.fast_wait = True
            yield

    def mc_arc(self, target, pl, position, offset, radius, a0, a1, alin, clockwise):
        center0 = position[a0] + offset[a0]
        center1 = position[a1] + offset[a1]
        r0 = -offset[a0]
        r1 = -offset[a1]
        rt0 = target[a0] - center0
        rt1 = target[a1] - center1
        angular = math.atan2(r0 * rt1 - r1 * rt0, r0 * rt0 + r1 * rt1)
        if clockwise:
            if angular >= -ARC_ANGULAR_TRAVEL_EPSILON:
                angular -= 2 * math.pi
        else:
            if angular <= ARC_ANGULAR_TRAVEL_EPSILON:
                angular += 2 * math.pi
        tol = self.s(12)
        denom = math.sqrt(max(tol * (2 * radius - tol), 1e-30))
        segments = int(math.floor(abs(0.5 * angular * radius) / denom))
        pos = list(position)
        if segments:
            if pl.inverse_time:
                pl.feed_rate *= segments
                pl.inverse_time = False
            theta = angular / segments
            lin = (target[alin] - position[alin]) / segments
            for i in range(1, segments):
                ct = math.cos(i * theta)
                sn = math.sin(i * theta)
                rr0 = -offset[a0] * ct + offset[a1] * sn
                rr1 = -offset[a0] * sn - offset[a1] * ct
                pos[a0] = center0 + rr0
                pos[a1] = center1 + rr1
                pos[alin] += lin
                yield from self.mc_line(list(pos), pl)
                if self.abort:
                    return
        yield from self.mc_line(list(target), pl)

    def mc_probe_cycle(self, target, pl, away, no_error):
        """No probe is wired: it never makes contact. Returns the parser's position update."""
        if self.state == STATE_CHECK_MODE:
            return "target"
        yield from self.buffer_synchronize()
        if self.abort:
            return "none"
        self.probe_succeeded = False
        triggered = bool(int(self.s(6))) ^ away
        if triggered:
            self.rt_alarm = ALARM_PROBE_FAIL_INITIAL
            yield from self.rt()
            return "none"
        yield from self.mc_line(target, pl)
        self.probe_active = True
        self.rt_state |= EXEC_CYCLE_START
        while True:
            yield from self.rt()
            if self.abort:
                return "none"
            if self.state == STATE_IDLE:
                break
            yield
        if no_error:
            self.probe_pos = list(self.sys_pos)
        else:
            self.rt_alarm = ALARM_PROBE_FAIL_CONTACT
        self.probe_active = False
        yield from self.rt()
        self.st_reset()
        self.plan_reset()
        self.plan_sync_position()
        self.report_probe()
        return "target"

    def wco_change(self):
        yield from self.buffer_synchronize()
        self.report_wco_counter = 0

    def write_coord_data(self, idx, vals):
        yield from self.buffer_synchronize()
        self.coord_data[idx] = list(vals)

    # ------------------------------------------------------------------ g-code
    def gc_execute_line(self, line):
        modal = self.modal.copy()
        jog = line.startswith("$")
        if jog:
            modal.motion = MOTION_LINEAR
            modal.feed_mode = 0
        axis_command = AXIS_CMD_NONE
        non_modal = NM_NONE
        axis_words = 0
        ijk_words = 0
        command_words = 0
        value_words = 0
        f = l_word = n_word = p = r = s = 0.0
        t = 0
        ijk = [0.0] * N_AXIS
        xyz = [0.0] * N_AXIS
        i = 3 if jog else 0
        while i < len(line):
            letter = line[i]
            if not ("A" <= letter <= "Z"):
                return E_EXPECTED_COMMAND_LETTER
            i += 1
            ok, value, i = read_float(line, i)
            if not ok:
                return E_BAD_NUMBER_FORMAT
            int_value = math.trunc(value) & 0xFF if abs(value) < 1e9 else 0xFF
            mantissa = c_round(100 * (value - int_value))
            if letter == "G":
                iv = int_value
                if iv in (10, 28, 30, 92) or iv in (4, 53):
                    if iv in (10, 28, 30, 92) and mantissa == 0:
                        if axis_command:
                            return E_AXIS_COMMAND_CONFLICT
                        axis_command = AXIS_CMD_NON_MODAL
                    word_bit = MG_G0
                    non_modal = iv
                    if iv in (28, 30, 92):
                        if mantissa not in (0, 10):
                            return E_UNSUPPORTED_COMMAND
                        non_modal += mantissa
                        mantissa = 0
                elif iv in (0, 1, 2, 3, 38):
                    if axis_command:
                        return E_AXIS_COMMAND_CONFLICT
                    axis_command = AXIS_CMD_MOTION
                    word_bit = MG_G1
                    modal.motion = iv
                    if iv == 38:
                        if mantissa not in (20, 30, 40, 50):
                            return E_UNSUPPORTED_COMMAND
                        modal.motion += mantissa // 10 + 100
                        mantissa = 0
                elif iv == 80:
                    word_bit = MG_G1
                    modal.motion = MOTION_NONE
                elif iv in (17, 18, 19):
                    word_bit = MG_G2
                    modal.plane = iv - 17
                elif iv in (90, 91):
                    if mantissa == 0:
                        word_bit = MG_G3
                        modal.distance = iv - 90
                    else:
                        word_bit = MG_G4
                        if mantissa != 10 or iv == 90:
                            return E_UNSUPPORTED_COMMAND
                        mantissa = 0
                elif iv in (93, 94):
                    word_bit = MG_G5
                    modal.feed_mode = 94 - iv
                elif iv in (20, 21):
                    word_bit = MG_G6
                    modal.units = 21 - iv
                elif iv == 40:
                    word_bit = MG_G7
                elif iv in (43, 49):
                    word_bit = MG_G8
                    if axis_command:
                        return E_AXIS_COMMAND_CONFLICT
                    axis_command = AXIS_CMD_TLO
                    if iv == 49:
                        modal.tool_length = 0
                    elif mantissa == 10:
                        modal.tool_length = 1
                    else:
                        return E_UNSUPPORTED_COMMAND
                    mantissa = 0
                elif 54 <= iv <= 59:
                    word_bit = MG_G12
                    modal.coord_select = iv - 54
                elif iv == 61:
                    word_bit = MG_G13
                    if mantissa != 0:
                        return E_UNSUPPORTED_COMMAND
                else:
                    return E_UNSUPPORTED_COMMAND
                if mantissa > 0:
                    return E_COMMAND_VALUE_NOT_INTEGER
                if command_words & (1 << word_bit):
                    return E_MODAL_GROUP_VIOLATION
                command_words |= 1 << word_bit
            elif letter == "M":
                if mantissa > 0:
                    return E_COMMAND_VALUE_NOT_INTEGER
                iv = int_value
                if iv in (0, 1, 2, 30):
                    word_bit = MG_M4
                    if iv == 0:
                        modal.program_flow = FLOW_PAUSED
                    elif iv != 1:
                        modal.program_flow = iv
                elif iv in (3, 4, 5):
                    word_bit = MG_M7
                    modal.spindle = {3: SPINDLE_CW, 4: SPINDLE_CCW, 5: SPINDLE_DISABLE}[iv]
                elif iv in (8, 9):
                    word_bit = MG_M8
                    if iv == 8:
                        modal.coolant |= COOLANT_FLOOD
                    else:
                        modal.coolant = 0
                else:
                    return E_UNSUPPORTED_COMMAND
                if command_words & (1 << word_bit):
                    return E_MODAL_GROUP_VIOLATION
                command_words |= 1 << word_bit
            else:
                if letter == "F":
                    f = value
                elif letter in "IJK":
                    k = "IJK".index(letter)
                    ijk[k] = value
                    ijk_words |= 1 << k
                elif letter == "L":
                    l_word = int_value
                elif letter == "N":
                    n_word = math.trunc(value)
                elif letter == "P":
                    p = value
                elif letter == "R":
                    r = value
                elif letter == "S":
                    s = value
                elif letter == "T":
                    if value > MAX_TOOL_NUMBER:
                        return E_MAX_VALUE_EXCEEDED
                    t = int_value
                elif letter in "XYZ":
                    k = "XYZ".index(letter)
                    xyz[k] = value
                    axis_words |= 1 << k
                else:
                    return E_UNSUPPORTED_COMMAND
                bit = WORD_BIT[letter]
                if value_words & bit:
                    return E_WORD_REPEATED
                if letter in "FNPTS" and value < 0.0:
                    return E_NEGATIVE_VALUE
                value_words |= bit

        # ---- STEP 3: error checks and conversions
        if axis_words and not axis_command:
            axis_command = AXIS_CMD_MOTION
        if value_words & WORD_BIT["N"] and n_word > MAX_LINE_NUMBER:
            return E_INVALID_LINE_NUMBER
        if jog:
            if not (value_words & WORD_BIT["F"]):
                return E_UNDEFINED_FEED_RATE
            if modal.units:
                f *= MM_PER_INCH
        else:
            if modal.feed_mode == 1:
                if axis_command == AXIS_CMD_MOTION:
                    if modal.motion not in (MOTION_NONE, MOTION_SEEK):
                        if not (value_words & WORD_BIT["F"]):
                            return E_UNDEFINED_FEED_RATE
            else:
                if self.modal.feed_mode == 0:
                    if value_words & WORD_BIT["F"]:
                        if modal.units:
                            f *= MM_PER_INCH
                    else:
                        f = self.gc_feed_rate
        if not (value_words & WORD_BIT["S"]):
            s = self.gc_spindle_speed
        if non_modal == NM_DWELL:
            if not (value_words & WORD_BIT["P"]):
                return E_VALUE_WORD_MISSING
            value_words &= ~WORD_BIT["P"]
        if modal.plane == 0:
            a0, a1, alin = 0, 1, 2
        elif modal.plane == 1:
            a0, a1, alin = 2, 0, 1
        else:
            a0, a1, alin = 1, 2, 0
        if modal.units:
            for k in range(N_AXIS):
                if axis_words & (1 << k):
                    xyz[k] *= MM_PER_INCH
        if axis_command == AXIS_CMD_TLO and modal.tool_length == 1:
            if axis_words ^ (1 << 2):
                return E_G43_DYNAMIC_AXIS_ERROR
        block_coord_system = list(self.coord_system)
        if command_words & (1 << MG_G12):
            if modal.coord_select != self.modal.coord_select:
                block_coord_system = list(self.coord_data[modal.coord_select])
        coord_select = 0
        position = self.gc_position
        if non_modal == NM_SET_COORD_DATA:
            if not axis_words:
                return E_NO_AXIS_WORDS
            if not (value_words & (WORD_BIT["P"] | WORD_BIT["L"])):
                return E_VALUE_WORD_MISSING
            coord_select = math.trunc(p)
            if coord_select > 6:
                return E_UNSUPPORTED_COORD_SYS
            if l_word != 20:
                if l_word == 2:
                    if value_words & WORD_BIT["R"]:
                        return E_UNSUPPORTED_COMMAND
                else:
                    return E_UNSUPPORTED_COMMAND
            value_words &= ~(WORD_BIT["L"] | WORD_BIT["P"])
            if coord_select > 0:
                coord_select -= 1
            else:
                coord_select = modal.coord_select
            ijk = list(self.coord_data[coord_select])
            for k in range(N_AXIS):
                if axis_words & (1 << k):
                    if l_word == 20:
                        ijk[k] = position[k] - self.coord_offset[k] - xyz[k]
                        if k == 2:
                            ijk[k] -= self.tool_length_offset
                    else:
                        ijk[k] = xyz[k]
        elif non_modal == NM_SET_COORD_OFFSET:
            if not axis_words:
                return E_NO_AXIS_WORDS
            for k in range(N_AXIS):
                if axis_words & (1 << k):
                    xyz[k] = position[k] - block_coord_system[k] - xyz[k]
                    if k == 2:
                        xyz[k] -= self.tool_length_offset
                else:
                    xyz[k] = self.coord_offset[k]
        else:
            if axis_command != AXIS_CMD_TLO and axis_words:
                for k in range(N_AXIS):
                    if not (axis_words & (1 << k)):
                        xyz[k] = position[k]
                    elif non_modal != NM_ABSOLUTE_OVERRIDE:
                        if modal.distance == 0:
                            xyz[k] += block_coord_system[k] + self.coord_offset[k]
                            if k == 2:
                                xyz[k] += self.tool_length_offset
                        else:
                            xyz[k] += position[k]
            if non_modal in (NM_GO_HOME_0, NM_GO_HOME_1):
                ijk = list(self.coord_data[6 if non_modal == NM_GO_HOME_0 else 7])
                if axis_words:
                    for k in range(N_AXIS):
                        if not (axis_words & (1 << k)):
                            ijk[k] = position[k]
                else:
                    axis_command = AXIS_CMD_NONE
            elif non_modal == NM_ABSOLUTE_OVERRIDE:
                if modal.motion not in (MOTION_SEEK, MOTION_LINEAR):
                    return E_G53_INVALID_MOTION_MODE
        clockwise = False
        probe_away = probe_no_error = False
        if modal.motion == MOTION_NONE:
            if axis_words:
                return E_AXIS_WORDS_EXIST
        elif axis_command == AXIS_CMD_MOTION:
            if modal.motion == MOTION_SEEK:
                if not axis_words:
                    axis_command = AXIS_CMD_NONE
            else:
                if f == 0.0:
                    return E_UNDEFINED_FEED_RATE
                if modal.motion == MOTION_LINEAR:
                    if not axis_words:
                        axis_command = AXIS_CMD_NONE
                elif modal.motion in (MOTION_CW_ARC, MOTION_CCW_ARC):
                    clockwise = modal.motion == MOTION_CW_ARC
                    if not axis_words:
                        return E_NO_AXIS_WORDS
                    if not (axis_words & ((1 << a0) | (1 << a1))):
                        return E_NO_AXIS_WORDS_IN_PLANE
                    x = xyz[a0] - position[a0]
                    y = xyz[a1] - position[a1]
                    if value_words & WORD_BIT["R"]:
                        value_words &= ~WORD_BIT["R"]
                        if all(abs(position[k] - xyz[k]) < 1e-12 for k in range(N_AXIS)):
                            return E_INVALID_TARGET
                        if modal.units:
                            r *= MM_PER_INCH
                        h = 4.0 * r * r - x * x - y * y
                        if h < 0:
                            return E_ARC_RADIUS_ERROR
                        h = -math.sqrt(h) / math.hypot(x, y)
                        if modal.motion == MOTION_CCW_ARC:
                            h = -h
                        if r < 0:
                            h = -h
                            r = -r
                        ijk[a0] = 0.5 * (x - (y * h))
                        ijk[a1] = 0.5 * (y + (x * h))
                    else:
                        if not (ijk_words & ((1 << a0) | (1 << a1))):
                            return E_NO_OFFSETS_IN_PLANE
                        value_words &= ~(WORD_BIT["I"] | WORD_BIT["J"] | WORD_BIT["K"])
                        if modal.units:
                            for k in range(N_AXIS):
                                if ijk_words & (1 << k):
                                    ijk[k] *= MM_PER_INCH
                        x -= ijk[a0]
                        y -= ijk[a1]
                        target_r = math.hypot(x, y)
                        r = math.hypot(ijk[a0], ijk[a1])
                        delta_r = abs(target_r - r)
                        if delta_r > 0.005:
                            if delta_r > 0.5:
                                return E_INVALID_TARGET
                            if delta_r > 0.001 * r:
                                return E_INVALID_TARGET
                else:  # probing
                    probe_no_error = modal.motion in (MOTION_PROBE_TOWARD_NO_ERROR,
                                                      MOTION_PROBE_AWAY_NO_ERROR)
                    probe_away = modal.motion in (MOTION_PROBE_AWAY, MOTION_PROBE_AWAY_NO_ERROR)
                    if not axis_words:
                        return E_NO_AXIS_WORDS
                    if all(abs(position[k] - xyz[k]) < 1e-12 for k in range(N_AXIS)):
                        return E_INVALID_TARGET
        if jog:
            value_words &= ~(WORD_BIT["N"] | WORD_BIT["F"])
        else:
            value_words &= ~(WORD_BIT["N"] | WORD_BIT["F"] | WORD_BIT["S"] | WORD_BIT["T"])
        if axis_command:
            value_words &= ~AXIS_WORD_BITS
        if value_words:
            return E_UNUSED_WORDS

        # ---- STEP 4: execute
        pl = PlanData()
        if jog:
            if command_words & ~((1 << MG_G3) | (1 << MG_G6) | (1 << MG_G0)):
                return E_INVALID_JOG_COMMAND
            if non_modal not in (NM_ABSOLUTE_OVERRIDE, NM_NONE):
                return E_INVALID_JOG_COMMAND
            pl.spindle_speed = self.gc_spindle_speed
            pl.spindle = self.modal.spindle
            pl.coolant = self.modal.coolant
            pl.feed_rate = f
            pl.no_feed_override = True
            pl.jog = True
            if self.soft_limits_enabled() and self.check_travel_limits(xyz):
                return E_TRAVEL_EXCEEDED
            yield from self.mc_line(list(xyz), pl)
            if self.state == STATE_IDLE and self.planner:
                self.state = STATE_JOG
                self.st_wake_up()
            self.gc_position = list(xyz)
            return OK

        laser_disable = laser_ismotion = laser_force_sync = False
        if self.laser_mode():
            if modal.motion not in (MOTION_LINEAR, MOTION_CW_ARC, MOTION_CCW_ARC):
                laser_disable = True
            if axis_words and axis_command == AXIS_CMD_MOTION:
                laser_ismotion = True
            elif self.modal.spindle == SPINDLE_CW:
                if self.modal.motion in (MOTION_LINEAR, MOTION_CW_ARC, MOTION_CCW_ARC):
                    if laser_disable:
                        laser_force_sync = True
                elif not laser_disable:
                    laser_force_sync = True

        self.modal.feed_mode = modal.feed_mode
        pl.inverse_time = bool(self.modal.feed_mode)
        self.gc_feed_rate = f
        pl.feed_rate = f
        if self.gc_spindle_speed != s or laser_force_sync:
            if self.modal.spindle != SPINDLE_DISABLE:
                if not laser_ismotion:
                    yield from self.spindle_sync(self.modal.spindle, 0.0 if laser_disable else s)
            self.gc_spindle_speed = s
        if not laser_disable:
            pl.spindle_speed = self.gc_spindle_speed
        self.gc_tool = t
        if self.modal.spindle != modal.spindle:
            yield from self.spindle_sync(modal.spindle, pl.spindle_speed)
            self.modal.spindle = modal.spindle
        pl.spindle = self.modal.spindle
        if self.modal.coolant != modal.coolant:
            yield from self.coolant_sync(modal.coolant)
            self.modal.coolant = modal.coolant
        pl.coolant = self.modal.coolant
        if non_modal == NM_DWELL:
            yield from self.mc_dwell(p)
        self.modal.plane = modal.plane
        self.modal.units = modal.units
        if axis_command == AXIS_CMD_TLO:
            self.modal.tool_length = modal.tool_length
            if self.modal.tool_length == 0:
                xyz[2] = 0.0
            if self.tool_length_offset != xyz[2]:
                self.tool_length_offset = xyz[2]
                yield from self.wco_change()
        if self.modal.coord_select != modal.coord_select:
            self.modal.coord_select = modal.coord_select
            self.coord_system = list(block_coord_system)
            yield from self.wco_change()
        self.modal.distance = modal.distance
        if non_modal == NM_SET_COORD_DATA:
            yield from self.write_coord_data(coord_select, ijk)
            if self.modal.coord_select == coord_select:
                self.coord_system = list(ijk)
                yield from self.wco_change()
        elif non_modal in (NM_GO_HOME_0, NM_GO_HOME_1):
            pl.rapid = True
            if axis_command:
                yield from self.mc_line(list(xyz), pl)
            yield from self.mc_line(list(ijk), pl)
            self.gc_position = list(ijk)
        elif non_modal == NM_SET_HOME_0:
            yield from self.write_coord_data(6, self.gc_position)
        elif non_modal == NM_SET_HOME_1:
            yield from self.write_coord_data(7, self.gc_position)
        elif non_modal == NM_SET_COORD_OFFSET:
            self.coord_offset = list(xyz)
            yield from self.wco_change()
        elif non_modal == NM_RESET_COORD_OFFSET:
            self.coord_offset = [0.0] * N_AXIS
            yield from self.wco_change()
        self.modal.motion = modal.motion
        if self.modal.motion != MOTION_NONE and axis_command == AXIS_CMD_MOTION:
            update = "target"
            if self.modal.motion == MOTION_LINEAR:
                yield from self.mc_line(list(xyz), pl)
            elif self.modal.motion == MOTION_SEEK:
                pl.rapid = True
                yield from self.mc_line(list(xyz), pl)
            elif self.modal.motion in (MOTION_CW_ARC, MOTION_CCW_ARC):
                yield from self.mc_arc(xyz, pl, list(self.gc_position), ijk, r, a0, a1, alin,
                                       clockwise)
            else:
                pl.no_feed_override = True
                update = yield from self.mc_probe_cycle(list(xyz), pl, probe_away, probe_no_error)
            if update == "target":
                self.gc_position = list(xyz)
        self.modal.program_flow = modal.program_flow
        if self.modal.program_flow:
            yield from self.buffer_synchronize()
            if self.modal.program_flow == FLOW_PAUSED:
                if self.state != STATE_CHECK_MODE:
                    self.rt_state |= EXEC_FEED_HOLD
                    yield from self.rt()
            else:
                m = self.modal
                m.motion = MOTION_LINEAR
                m.plane = 0
                m.distance = 0
                m.feed_mode = 0
                m.coord_select = 0
                m.spindle = SPINDLE_DISABLE
                m.coolant = 0
                self.f_override = self.r_override = self.s_override = 100
                if self.state != STATE_CHECK_MODE:
                    self.coord_system = list(self.coord_data[0])
                    yield from self.wco_change()
                    self.spindle_set_state(SPINDLE_DISABLE, 0.0)
                    self.coolant_on = 0
                self.msg("Pgm End")
            self.modal.program_flow = FLOW_RUNNING
        return OK

    # ------------------------------------------------------------------ pty & event loop
    def open_pty(self):
        master, slave = os.openpty()
        self.slave_name = os.ttyname(slave)
        for fd in (master, slave):
            tty.setraw(fd, termios.TCSANOW)
        os.close(slave)
        os.set_blocking(master, False)
        self.master = master
        self.link = None
        if self.args.link:
            try:
                if os.path.islink(self.args.link):
                    os.unlink(self.args.link)
            except OSError:
                pass
            os.symlink(self.slave_name, self.args.link)
            self.link = self.args.link
        sys.stdout.write(self.slave_name + "\n")
        sys.stdout.flush()

    def cleanup(self):
        if self.link:
            try:
                if os.path.islink(self.link) and os.readlink(self.link) == self.slave_name:
                    os.unlink(self.link)
            except OSError:
                pass
            self.link = None
        if self.master is not None:
            try:
                os.close(self.master)
            except OSError:
                pass
            self.master = None
        if self.logf:
            self.logf.close()
            self.logf = None

    def vanish(self):
        if self.args.verbose:
            sys.stderr.write("-- vanishing\n")
        self.cleanup()
        os._exit(0)

    def flush_tx(self):
        """Write pending output; False when the pty would block."""
        while self.tx and self.master is not None:
            try:
                n = os.write(self.master, self.tx)
            except BlockingIOError:
                return False
            except OSError as e:
                if e.errno in (errno.EIO, errno.EAGAIN):
                    return False
                raise
            del self.tx[:n]
        return True

    def read_input(self):
        """Move what the client wrote into the 'wire' (the USB-serial link)."""
        while True:
            try:
                data = os.read(self.master, 4096)
            except BlockingIOError:
                self.connected = True
                return
            except OSError as e:
                if e.errno == errno.EIO:  # no client has the slave open
                    self.connected = False
                    return
                raise
            if not data:
                self.connected = False
                return
            self.connected = True
            if not self.wire:
                self.wire_t0 = time.monotonic()
            self.wire += data

    def deliver_wire(self, main):
        """Hand the bytes that have arrived at the baud rate to the receive ISR;
        the main program runs after each end of line, as it would on the MCU."""
        if not self.wire:
            return
        n = min(int((time.monotonic() - self.wire_t0) * self.byte_rate), len(self.wire))
        if n <= 0:
            return
        chunk = bytes(self.wire[:n])
        del self.wire[:n]
        self.wire_t0 += n / self.byte_rate
        for b in chunk:
            self.isr_rx(b)
            if b in (10, 13):
                self.stepper_tick()
                next(main)

    def run(self):
        self.open_pty()
        main = self.firmware()
        self.sim_last = self.sim_now()
        while self.running:
            self.read_input()
            self.deliver_wire(main)
            self.stepper_tick()
            self.fast_wait = False
            next(main)
            blocked = not self.flush_tx()
            busy = self.st_running or self.fast_wait or self.rx or self.wire
            timeout = 0.002 if busy else 0.05
            # a blocked pty is retried on the next tick; no select on writability
            # (it can report writable while a write still gets EAGAIN)
            if blocked:
                timeout = min(timeout, 0.01)
            if not self.connected:
                # reads fail with EIO while no client has the slave open and select
                # would report the master readable all the time: poll instead
                time.sleep(min(timeout, 0.02))
            else:
                select.select([self.master], [], [], timeout)


def parse_setting(text):
    try:
        n, v = text.lstrip("$").split("=", 1)
        n = int(n)
        v = float(v)
    except ValueError:
        raise argparse.ArgumentTypeError("expected N=VALUE, e.g. 120=10")
    if n not in SETTING_KINDS:
        raise argparse.ArgumentTypeError("no GRBL setting $%d" % n)
    return n, v


def main(argv=None):
    ap = argparse.ArgumentParser(
        description="GRBL 1.1h controller emulator on a pseudo-terminal (see the module docstring).")
    ap.add_argument("--link", metavar="PATH", help="also make the symlink PATH -> pty slave")
    ap.add_argument("--no-homing", action="store_true", help="$22=0 (and so $20=0): start Idle")
    ap.add_argument("--negative-space", action="store_true",
                    help="stock GRBL machine space -max travel..0 (default: 0..+max travel)")
    ap.add_argument("--home-distance", type=float, default=10.0, metavar="MM",
                    help="distance of the carriage from its home switch at power-up (10)")
    ap.add_argument("--setting", dest="preset", action="append", default=[], type=parse_setting,
                    metavar="N=V", help="preset $N=V at power-up (repeatable)")
    ap.add_argument("--baud", type=int, default=115200,
                    help="pace the client's bytes as a serial link at this rate would (115200)")
    ap.add_argument("--time-scale", type=float, default=1.0, metavar="X",
                    help="multiply motion/homing/dwell/alarm-delay durations by X (1.0)")
    ap.add_argument("--drop-ok", type=int, action="append", default=[], metavar="N",
                    help="do not send the final ok/error of line N (repeatable)")
    ap.add_argument("--garbage-after", type=int, action="append", default=[], metavar="N",
                    help="send a garbage line after answering line N (repeatable)")
    ap.add_argument("--silent-after", type=int, metavar="N",
                    help="after answering line N, send nothing any more")
    ap.add_argument("--vanish-after", type=int, metavar="N",
                    help="when line N arrives, close the pty and exit")
    ap.add_argument("--log", metavar="FILE", help="append every received line to FILE")
    ap.add_argument("--log-realtime", action="store_true",
                    help="with --log, also log real-time bytes as <?>, <!>, <~>, <0x18>, ...")
    ap.add_argument("--merge-crlf", action="store_true",
                    help="treat \\r\\n as one line end (real GRBL answers the empty line too)")
    ap.add_argument("--plain-status", action="store_true",
                    help="leave the |WCO: and |Ov: fields out of status reports")
    ap.add_argument("--verbose", action="store_true", help="trace traffic on stderr")
    args = ap.parse_args(argv)
    if args.time_scale <= 0:
        ap.error("--time-scale must be > 0")
    args.drop_ok = set(args.drop_ok)
    args.garbage_after = set(args.garbage_after)

    emu = Emulator(args)

    def on_signal(signum, frame):
        emu.cleanup()
        sys.exit(0)

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGHUP, on_signal)
    try:
        emu.run()
    finally:
        emu.cleanup()


if __name__ == "__main__":
    main()
