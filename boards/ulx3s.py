"""FLISS on the ULX3S with the ECP5-85F (LFE5U-85F-6BG381C), on top of amaranth-boards.

Clock: the 25 MHz oscillator through an ``EHXPLLL``; 80 MHz exactly. Pins: the GPIO header,
GP0-GP12 and GN0-GN12 (see ``docs/boards.md``); UART on the FT231X.
"""

from amaranth.build import Attrs, Pins
from amaranth.hdl import Const, Instance, Signal
from amaranth.lib import io

try:
    from amaranth_boards.ulx3s import ULX3S_85F_Platform
except ImportError as error:  # pragma: no cover - depends on the installed extras
    raise ImportError("The ULX3S platform needs amaranth-boards: "
                      "pip install -e '.[boards]'") from error

from ..hdl.finetdc.line import SCRIPT_AFTER_SYNTH
from . import FlissPlatform, PllClocking


__all__ = ["Ecp5PllConfig", "ecp5_pll", "FlissULX3SPlatform"]


class Ecp5PllConfig:
    """Divider settings of an ECP5 ``EHXPLLL`` with feedback from ``CLKOP``.

    ``f_out = f_in * clkfb_div / clki_div``; the VCO runs at ``f_out * clkop_div``.
    """

    def __init__(self, f_in_hz, clki_div, clkfb_div, clkop_div):
        self.f_in_hz = f_in_hz
        self.clki_div = clki_div
        self.clkfb_div = clkfb_div
        self.clkop_div = clkop_div

    @property
    def f_pfd_hz(self):
        """Phase detector frequency, in Hz."""
        return self.f_in_hz / self.clki_div

    @property
    def f_out_hz(self):
        """Output frequency, in Hz."""
        return self.f_pfd_hz * self.clkfb_div

    @property
    def f_vco_hz(self):
        """VCO frequency, in Hz."""
        return self.f_out_hz * self.clkop_div

    def __repr__(self):
        return (f"Ecp5PllConfig(f_in_hz={self.f_in_hz}, clki_div={self.clki_div}, "
                f"clkfb_div={self.clkfb_div}, clkop_div={self.clkop_div})"
                f"  # {self.f_out_hz / 1e6:.4f} MHz")


def ecp5_pll(f_in_hz, f_out_hz):
    """Closest :class:`Ecp5PllConfig` to ``f_out_hz``; among equals, the VCO nearest 600 MHz.

    Limits (ECP5 datasheet): input 8 to 400 MHz, phase detector 3.125 to 400 MHz, VCO 400 to
    800 MHz, output 3.125 to 400 MHz, ``clki_div`` 1 to 128, ``clkfb_div`` 1 to 80,
    ``clkop_div`` 1 to 128.
    """
    if not 3.125e6 <= f_out_hz <= 400e6:
        raise ValueError(f"The ECP5 PLL makes 3.125 to 400 MHz, not {f_out_hz / 1e6} MHz")
    best = None
    for clki_div in range(1, 129):
        if not 3.125e6 <= f_in_hz / clki_div <= 400e6:
            continue
        for clkfb_div in range(1, 81):
            f_out = f_in_hz / clki_div * clkfb_div
            if not 3.125e6 <= f_out <= 400e6:
                continue
            for clkop_div in range(1, 129):
                config = Ecp5PllConfig(f_in_hz, clki_div, clkfb_div, clkop_div)
                if not 400e6 <= config.f_vco_hz <= 800e6:
                    continue
                key = (abs(f_out - f_out_hz), abs(config.f_vco_hz - 600e6))
                if best is None or key < best[0]:
                    best = key, config
    if best is None:
        raise ValueError(f"The ECP5 PLL cannot make {f_out_hz / 1e6} MHz from "
                         f"{f_in_hz / 1e6} MHz")
    return best[1]


class _ECP5Clocking(PllClocking):
    def pll(self, m, platform):
        config = platform.pll_config
        clk25 = platform.request(platform.default_clk, dir="-")
        m.submodules.clk25_buffer = clk25_buffer = io.Buffer("i", clk25)
        clock = Signal()
        lock = Signal()
        m.submodules.pll = Instance("EHXPLLL",
            p_PLLRST_ENA="DISABLED",
            p_INTFB_WAKE="DISABLED",
            p_STDBY_ENABLE="DISABLED",
            p_DPHASE_SOURCE="DISABLED",
            p_OUTDIVIDER_MUXA="DIVA",
            p_OUTDIVIDER_MUXB="DIVB",
            p_OUTDIVIDER_MUXC="DIVC",
            p_OUTDIVIDER_MUXD="DIVD",
            p_CLKI_DIV=config.clki_div,
            p_CLKFB_DIV=config.clkfb_div,
            p_CLKOP_ENABLE="ENABLED",
            p_CLKOP_DIV=config.clkop_div,
            p_CLKOP_CPHASE=(config.clkop_div - 1) // 2,   # 0 degrees
            p_CLKOP_FPHASE=0,
            p_FEEDBK_PATH="CLKOP",
            # Loop filter settings that Lattice's tools write for every configuration
            a_ICP_CURRENT="12",
            a_LPF_RESISTOR="8",
            a_MFG_ENABLE_FILTEROPAMP="1",
            a_MFG_GMCREF_SEL="2",
            a_FREQUENCY_PIN_CLKI=f"{config.f_in_hz / 1e6:g}",
            a_FREQUENCY_PIN_CLKOP=f"{config.f_out_hz / 1e6:g}",
            i_CLKI=clk25_buffer.i,
            i_CLKFB=clock,
            i_RST=Const(0),
            i_STDBY=Const(0),
            # Dynamic phase shift unused: its strobes act on falling edges, so hold them high
            i_PHASESEL0=Const(0),
            i_PHASESEL1=Const(0),
            i_PHASEDIR=Const(1),
            i_PHASESTEP=Const(1),
            i_PHASELOADREG=Const(1),
            i_PLLWAKESYNC=Const(0),
            i_ENCLKOP=Const(0),
            o_CLKOP=clock,
            o_LOCK=lock,
        )
        return clock, lock


# GPIO header pins by their silkscreen names: GPn is connector pin "n+", GNn is "n-".
_PINS = {
    "laser":     "0+",
    "tdc_start": "0-",
    "aggressor": "1+",
    "photon":    "1-",
    "valid":     "2+",
    "collision": "2-",
    "timestamp": "3+ 3- 4+ 4- 5+ 5- 6+ 6- 7+ 7- 8+ 8- 9+",
    "address":   "9- 10+ 10- 11+ 11- 12+",
}


def _ecp5_85_block_ram_quads():
    """The LFE5U-85F's 208 ``DP16KD`` sites (nextpnr's BEL names) in quads of four side by side:
    four rows of 13 quads. Every third quad of a row (the ends and the middle) comes last, so
    that the first 32 leave room between them for the routing and the other block RAMs; within
    that, nearest the middle of the fabric (126 by 95 tiles) first."""
    rows = (22, 46, 70, 82)
    starts = (4, 13, 22, 31, 40, 49, 58, 69, 78, 87, 96, 105, 114)   # (EBR0..3 at x, x+2, ...)
    middle_x, middle_y = 126 // 2, 95 // 2
    order = sorted((n % 3 == 0, abs(x + 3 - middle_x) + abs(y - middle_y), y, x)
                   for y in rows for n, x in enumerate(starts))
    return tuple(tuple(f"X{x + 2 * n}/Y{y}/EBR{n}" for n in range(4)) for *_, y, x in order)


class FlissULX3SPlatform(FlissPlatform, ULX3S_85F_Platform):
    """ULX3S (ECP5-85F) with the FLISS pins and a PLL to the design clock
    (:class:`FlissPlatform`): 80 MHz exactly when 80 MHz is asked."""

    board = "ulx3s"
    pins = _PINS
    #: Where the histogram places its banks' block RAMs, a quad for each group of its read
    #: tree (:class:`~fliss.hdl.histogram.dual.DualPortBanks`).
    block_ram_quads = _ecp5_85_block_ram_quads()
    pll_search = staticmethod(ecp5_pll)
    clocking_class = _ECP5Clocking
    #: The fine TDC's carry chain, hidden from yosys as boxes, becomes ``CCU2C`` cells.
    script_after_synth = SCRIPT_AFTER_SYNTH

    @staticmethod
    def fliss_io(pins, direction):
        # Inputs have pull-downs, so that an unconnected sensor bus reads as idle. Outputs may
        # be read back (a design input `<output>_pad`, the fine TDC's internal loopback): their
        # pins are bidirectional, the buffer an output one unless a design reads the pad.
        if direction == "i":
            attrs = Attrs(IO_TYPE="LVCMOS33", PULLMODE="DOWN")
        else:
            attrs = Attrs(IO_TYPE="LVCMOS33", DRIVE="8", SLEWRATE="FAST")
            direction = "io"
        return Pins(pins, dir=direction, conn=("gpio", 0)), attrs

    @property
    def required_tools(self):
        # openFPGALoader programs the board; building does not need it.
        return [tool for tool in super().required_tools if tool != "openFPGALoader"]

    def programmers(self, bitstream):
        """Commands that program ``bitstream`` (the ``.bit``) into the FPGA's SRAM, most
        preferred first: ``[(tool, argv), ...]``."""
        return [
            ("openFPGALoader", ["openFPGALoader", "-b", "ulx3s", bitstream]),
            ("fujprog",        ["fujprog", bitstream]),
        ]

    #: Bitstream file extension of this board.
    bitstream_ext = "bit"
