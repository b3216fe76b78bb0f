"""The servo axis's TOML options (pydantic v2 models) and its word map.

`[devices.NAME]` with `type = "servo_axis"`; every key is optional except `plant.K`:

    words = "%MW200"            # first word of the axis's block (the word map below)
    servo_clock_hz = 2258.65    # servo interrupt rate (Turbo PMAC2 default: 9034.6 Hz / 4),
                                # up to 50 kHz
    counts_per_mm = 409.6       # encoder counts per mm (display and the host command), <= 1e6
    start = -20000.0            # true carriage position at power-up, counts from home
    require_home = true         # a move or jog before homing is a fatal error
    estop_input = "%I0.0"       # E-stop push button (1 = pressed), also read by the program
    power_output = "%Q0.3"      # contactor feeding the drive's ENA-PWR (unset: always on)
    fault = "none"              # "jammed" | "estop" | "amp_fault" | "none" (also set_fault)
    trace = true                # servo-rate trace (t, CP, AP, FE, u) in memory
    trace_max = 200000          # rows kept (a ring), up to 10,000,000
    trace_csv = "servo_X.csv"   # also written at close()
    load_mass_word = "%MF290"   # optional: a %MF the device reads every scan: a change of
                                # plant.load_mass_ratio at run time (0 after a cold start:
                                # the configured mass; the sum is kept >= 0)
    ivar_words = "%MW400"       # optional: the I-variables and the load disturbance as
                                # words a host reads and writes while running (ivars.py)
    [devices.NAME.geometry]     # counts, true positions from the home index mark
    index_period = 4096.0       # one index (C) pulse per motor revolution, at x = 0 mod 4096
    home_switch = [-1024.0, 6144.0]    # the home flag is made in [lo, hi)
    limit_plus = 4096.0         # END-1, wired to the drive (no torque further +); unset: none
    limit_minus = -217088.0     # END-0
    hard_stop_plus = 6144.0     # rubber end stops: the carriage stops dead there
    hard_stop_minus = -219136.0
    limit_wiring = "drive"      # where END-0/END-1 are wired: "drive" (it refuses torque
                                # that way; the PMAC keeps commanding: fatal FE, the servo
                                # table) or "pmac" (its limit inputs, Ixx24 bit 17 = 0: an
                                # abort at limit_decel, the loop holds, moves away only)
    limit_decel = 0.25          # Ixx15: deceleration on a "pmac" limit, counts/ms^2
    [devices.NAME.plant]        # x'' = K sat(u + amp_offset) - a x' - K coulomb sgn(x') - K load
    K = 11157.2                 # counts/s^2 per DAC bit (required)
    a = 0.0                     # viscous term B/J, 1/s
    coulomb = 31.0              # Coulomb friction, DAC bits (with stiction)
    amp_offset = -3.0           # amplifier input offset, DAC bits
    u_peak = 516.0              # drive current limit, DAC bits (0: none)
    load = 0.0                  # constant load force, DAC bits (thesis F_p)
    load_table = []             # [[x, bits], ...]: position-dependent load, linear between
    load_mass_ratio = 0.0       # extra moving mass over the motor-side inertia: K, a / (1 + r)
    encoder = "floor"           # "floor" (integer counts) or "ideal" (exact position)
    dac_bits = 12               # 12-bit DAC: u = 16 floor(u / 16); 0: real-valued
    [devices.NAME.ivars]        # PMAC I-variables, by I-name or plain name (law.IVARS)
    Ixx30 = 7990                # or kp = 7990 ...
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from softplc.devices.axis.law import Gains

DEFAULT_SERVO_CLOCK_HZ = 9034.6 / 4  # Turbo PMAC2 default phase clock / 4 [manual]
FAULTS = ("none", "jammed", "estop", "amp_fault")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class PlantOptions(_Strict):
    K: float = Field(gt=0)
    a: float = Field(0.0, ge=0)
    coulomb: float = Field(0.0, ge=0)
    amp_offset: float = 0.0
    u_peak: float = Field(0.0, ge=0)
    load: float = 0.0
    load_table: list[tuple[float, float]] = []
    load_mass_ratio: float = Field(0.0, ge=0)
    encoder: Literal["floor", "ideal"] = "floor"
    dac_bits: int = Field(12, ge=0, le=16)

    @model_validator(mode="after")
    def _sorted_table(self) -> PlantOptions:
        xs = [x for x, _ in self.load_table]
        if xs != sorted(xs) or len(set(xs)) != len(xs):
            raise ValueError("load_table positions must be strictly increasing")
        return self


class GeometryOptions(_Strict):
    index_period: float = Field(4096.0, gt=0)
    index_offset: float = 0.0
    home_switch: tuple[float, float] = (-1024.0, 6144.0)
    limit_plus: float | None = None
    limit_minus: float | None = None
    hard_stop_plus: float | None = None
    hard_stop_minus: float | None = None
    limit_wiring: Literal["drive", "pmac"] = "drive"
    limit_decel: float = Field(0.25, gt=0, allow_inf_nan=False)  # Ixx15, counts/ms^2


class ServoAxisOptions(_Strict):
    words: str = "%MW200"
    # bounded: each scan runs clock x period servo ticks (1e308 crashed, 1e7 took 0.2 s)
    servo_clock_hz: float = Field(DEFAULT_SERVO_CLOCK_HZ, gt=0, le=50_000)
    counts_per_mm: float = Field(409.6, gt=0, le=1e6)
    start: float = 0.0
    require_home: bool = True
    estop_input: str | None = None
    power_output: str | None = None
    fault: Literal["none", "jammed", "estop", "amp_fault"] = "none"
    trace: bool = True
    trace_max: int = Field(200_000, gt=0, le=10_000_000)
    trace_csv: str | None = None
    load_mass_word: str | None = None
    ivar_words: str | None = None
    geometry: GeometryOptions = GeometryOptions()
    plant: PlantOptions
    ivars: Gains = Field(default_factory=Gains)  # type: ignore[valid-type]


class Word:
    """Offsets of the word block from `words` (X at %MW200, Y at %MW230 in servo_table).

    Command words (written by the program, read by the device once per scan): 0..9.
    Status words (written by the device after its ticks; read-only for Modbus): 10..27.
    """

    TARGET = 0  # %MD: absolute target, counts
    SPEED = 2  # %MD: counts/s (0 = Ixx22)
    ACC_TIME = 4  # %MW: ms (0 = Ixx20); parabolic: move time; open loop: duration
    SCURVE_TIME = 5  # %MW: ms (0 = Ixx21)
    CONTROL = 6  # %MW: bits, class Ctl
    MODE = 7  # %MW: class Mode
    OPEN_LOOP = 8  # %MW: open-loop output, 0.01 % of Ixx69 (signed)
    COMMAND_WORDS = 10
    ACTUAL = 10  # %MD: counts
    COMMANDED = 12  # %MD: counts (rounded)
    FE = 14  # %MF: following error, counts
    FE_MAX = 16  # %MF: max |FE| since the last EXECUTE or HOME
    STATUS = 18  # %MW: bits, class St
    ERROR = 19  # %MW: class Err
    TICKS = 20  # %MD: servo loop cycles (wraps at 2^31)
    OUTPUT = 22  # %MF: DAC output, bits
    CURRENT = 24  # %MF: drive command after its current limit, % of u_peak (torque signal)
    VELOCITY = 26  # %MF: actual velocity, counts/s (over the last scan)
    SIZE = 28


class Ctl:
    ENABLE, EXECUTE, HOME, STOP, KILL, RESET, JOG_PLUS, JOG_MINUS = (1 << k for k in range(8))


class Mode:
    SCURVE, TRAPEZOID, STEP, PARABOLIC, OPEN_LOOP = range(5)


class St:
    (ENABLED, BUSY, IN_POSITION, DONE, HOMED, FE_WARNING, FE_FATAL, AMP_FAULT, LIMIT_PLUS,
     LIMIT_MINUS, ESTOP, ERROR, HOMING, OPEN_LOOP) = (1 << k for k in range(14))


class Err:
    NONE, FATAL_FE, AMP_FAULT, LIMIT, NOT_HOMED, BAD_COMMAND = range(6)
    TEXT = ("none", "fatal following error", "amplifier fault / E-stop", "limit switch",
            "not homed", "bad command")
