"""``fliss generate``: the top level as Verilog, for users who build with their own tools."""

from pathlib import Path

from ..hdl import DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ, period_cycles
from ..hdl.protocol import DEFAULT_BAUD
from ..hdl.top import FlissTop
from ..hdl.uart import bit_cycles
from ..hdl.verilog import convert
from .cli import UserError
from .units import parse_baud, parse_frequency


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "generate", formatter_class=formatter,
        help="write the FLISS top level as Verilog (port list in docs/ports.md)",
        description="Writes fliss_top.v: module fliss_top with a clock `clk`, a synchronous "
                    "active-high reset `rst` and the pins listed in docs/ports.md.")
    parser.add_argument("-o", "--output", default="build/verilog", metavar="DIR",
                        help="output folder")
    parser.add_argument("--clock", default=f"{DEFAULT_CLOCK_HZ // 1_000_000}MHz", metavar="HZ",
                        help="clock frequency of `clk`")
    parser.add_argument("--baud", default=f"{DEFAULT_BAUD // 1_000_000}M", metavar="BAUD",
                        help="UART baud rate (3M, 115200, ...)")
    parser.add_argument("--name", default="fliss_top", help="Verilog module name")
    parser.set_defaults(run=run)


def run(args):
    try:
        clock_hz = parse_frequency(args.clock)
        baud = parse_baud(args.baud)
        period_cycles(clock_hz, DEFAULT_PRF_HZ)
        bit_cycles(clock_hz, baud)   # check before the top level is made
        top = FlissTop(clock_hz=int(clock_hz), baud=int(baud))
    except ValueError as error:
        raise UserError(str(error)) from None
    output = Path(args.output)
    try:
        output.mkdir(parents=True, exist_ok=True)
        path = output / f"{args.name}.v"
        path.write_text(convert(top, args.name))
    except OSError as error:
        raise UserError(f"cannot write {args.output}: {error.strerror}") from None
    print(path)
