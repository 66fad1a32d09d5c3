"""FLISS on the iCEBreaker (iCE40UP5K-SG48), on top of amaranth-boards.

Clock: the 12 MHz oscillator through the iCE40 PLL; 80 MHz asked gives 79.5 MHz, the closest the
PLL makes. Pins: the three PMOD connectors (see ``docs/boards.md``); UART on the FT2232H.
"""

from amaranth.build import Attrs, Pins
from amaranth.hdl import Const, Instance, Signal

try:
    from amaranth_boards.icebreaker import ICEBreakerPlatform
except ImportError as error:  # pragma: no cover - depends on the installed extras
    raise ImportError("The iCEBreaker platform needs amaranth-boards: "
                      "pip install -e '.[boards]'") from error

from . import FlissPlatform, PllClocking


__all__ = ["Ice40PllConfig", "ice40_pll", "FlissICEBreakerPlatform"]


class Ice40PllConfig:
    """Divider settings of an iCE40 ``SB_PLL40`` in ``SIMPLE`` feedback mode.

    ``f_out = f_in * (divf + 1) / ((divr + 1) * 2**divq)``.
    """

    def __init__(self, f_in_hz, divr, divf, divq):
        self.f_in_hz = f_in_hz
        self.divr = divr
        self.divf = divf
        self.divq = divq

    @property
    def f_pfd_hz(self):
        """Phase detector frequency, in Hz."""
        return self.f_in_hz / (self.divr + 1)

    @property
    def f_vco_hz(self):
        """VCO frequency, in Hz."""
        return self.f_pfd_hz * (self.divf + 1)

    @property
    def f_out_hz(self):
        """Output frequency, in Hz."""
        return self.f_vco_hz / 2 ** self.divq

    @property
    def filter_range(self):
        """Loop filter setting for the phase detector frequency (iCE40 sysCLOCK PLL guide)."""
        for filter_range, f_max_mhz in enumerate((17, 26, 44, 66, 101), start=1):
            if self.f_pfd_hz < f_max_mhz * 1e6:
                return filter_range
        return 6

    def __repr__(self):
        return (f"Ice40PllConfig(f_in_hz={self.f_in_hz}, divr={self.divr}, divf={self.divf}, "
                f"divq={self.divq})  # {self.f_out_hz / 1e6:.4f} MHz")


def ice40_pll(f_in_hz, f_out_hz):
    """Closest :class:`Ice40PllConfig` to ``f_out_hz``; among equals, the lowest VCO frequency.

    Limits (iCE40 datasheet): phase detector 10 to 133 MHz, VCO 533 to 1066 MHz, output 16 to
    275 MHz, ``divr`` 0 to 15, ``divf`` 0 to 127, ``divq`` 1 to 6.
    """
    if not 16e6 <= f_out_hz <= 275e6:
        raise ValueError(f"The iCE40 PLL makes 16 to 275 MHz, not {f_out_hz / 1e6} MHz")
    best = None
    for divr in range(16):
        for divq in range(1, 7):
            for divf in range(128):
                config = Ice40PllConfig(f_in_hz, divr, divf, divq)
                if not (10e6 <= config.f_pfd_hz <= 133e6 and
                        533e6 <= config.f_vco_hz <= 1066e6):
                    continue
                key = (abs(config.f_out_hz - f_out_hz), config.f_vco_hz)
                if best is None or key < best[0]:
                    best = key, config
    if best is None:
        raise ValueError(f"The iCE40 PLL cannot make {f_out_hz / 1e6} MHz from "
                         f"{f_in_hz / 1e6} MHz")
    return best[1]


class _ICE40Clocking(PllClocking):
    def pll(self, m, platform):
        config = platform.pll_config
        clk12 = platform.request(platform.default_clk, dir="-")
        clock = Signal()
        lock = Signal()
        m.submodules.pll = Instance("SB_PLL40_PAD",
            p_FEEDBACK_PATH="SIMPLE",
            p_DIVR=config.divr,
            p_DIVF=config.divf,
            p_DIVQ=config.divq,
            p_FILTER_RANGE=config.filter_range,
            i_PACKAGEPIN=clk12.io,
            i_RESETB=Const(1),
            i_BYPASS=Const(0),
            o_PLLOUTGLOBAL=clock,
            o_LOCK=lock,
        )
        return clock, lock


# PMOD connectors: pins 1-4 on the top row, 7-10 on the bottom row (5, 11: GND; 6, 12: 3.3 V).
# PMOD2 is the connector of the break-off LED and button board: snap it off (or unplug it).
# The coarse photon-hit input and the sensor's collision flag share PMOD2 pin 4: 24 pins for
# 25 signals. Wire the one in use; the TDC source setting picks which path reads it.
_PINS = {
    "timestamp": "pmod_0:1 pmod_0:2 pmod_0:3 pmod_0:4 pmod_0:7 pmod_0:8 pmod_0:9 pmod_0:10 "
                 "pmod_1:1 pmod_1:2 pmod_1:3 pmod_1:4 pmod_1:7",
    "address":   "pmod_1:8 pmod_1:9 pmod_1:10 pmod_2:7 pmod_2:8 pmod_2:9",
    "valid":     "pmod_2:10",
    "laser":     "pmod_2:1",
    "tdc_start": "pmod_2:2",
    "aggressor": "pmod_2:3",
    "photon":    "pmod_2:4",
}

#: Design ports that share the pins of another one: name -> name of the resource.
SHARED_PINS = {"collision": "photon"}


class FlissICEBreakerPlatform(FlissPlatform, ICEBreakerPlatform):
    """iCEBreaker with the FLISS pins and a PLL to the design clock (:class:`FlissPlatform`):
    79.5 MHz when 80 MHz is asked."""

    board = "icebreaker"
    pins = _PINS
    shared_pins = SHARED_PINS
    pll_search = staticmethod(ice40_pll)
    clocking_class = _ICE40Clocking
    # Flip-flops get a clock enable only where at least 8 share it. Each logic block's 8 cells
    # share one clock enable, so at 89 % of the UP5K rare enables leave nextpnr's placer no
    # legal placement ("Unable to find legal placement for all cells", with every seed tried);
    # with this the build places, at about 60 more cells.
    synth_opts = ("-dffe_min_ce_use", "8")

    @staticmethod
    def fliss_io(pins, direction):
        return Pins(pins, dir=direction), Attrs(IO_STANDARD="SB_LVCMOS")

    def programmers(self, bitstream):
        """Commands that program ``bitstream`` (the ``.bin``) into the FPGA, most preferred
        first: ``[(tool, argv), ...]``. Both load the configuration flash over the FT2232H."""
        return [
            ("iceprog",        ["iceprog", bitstream]),
            ("openFPGALoader", ["openFPGALoader", "-b", "ice40_generic", "-f", bitstream]),
        ]

    #: Bitstream file extension of this board.
    bitstream_ext = "bin"
