"""``fliss generate``: the top level as Verilog, for users who build with their own tools."""

import re

from ...hdl.clock import DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ, bit_cycles, period_cycles
from ...hdl.protocol import DEFAULT_BAUD
from ...hdl.top import FlissTop
from ...hdl.verilog import convert
from ..errors import UserError
from ..paths import check_output_dir
from ..units import parse_baud, parse_frequency


# A Verilog simple identifier (IEEE 1364 section 3.7.3), also the file name.
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_$]*\Z")
# Verilog-2005 keywords a module cannot be named.
_KEYWORDS = set("""always and assign automatic begin buf bufif0 bufif1 case casex casez cell cmos
config deassign default defparam design disable edge else end endcase endconfig endfunction
endgenerate endmodule endprimitive endspecify endtable endtask event for force forever fork
function generate genvar highz0 highz1 if ifnone incdir include initial inout input instance
integer join large liblist library localparam macromodule medium module nand negedge nmos nor
noshowcancelled not notif0 notif1 or output parameter pmos posedge primitive pull0 pull1 pulldown
pullup pulsestyle_onevent pulsestyle_ondetect rcmos real realtime reg release repeat rnmos rpmos
rtran rtranif0 rtranif1 scalared showcancelled signed small specify specparam strong0 strong1
supply0 supply1 table task time tran tranif0 tranif1 tri tri0 tri1 triand trior trireg unsigned
use uwire vectored wait wand weak0 weak1 while wire wor xnor xor""".split())


def check_module_name(name):
    """Refuse (:exc:`UserError`) a module name that is not a Verilog identifier or is a
    keyword; it also names the file, so it holds no path."""
    if not _IDENTIFIER.match(name) or len(name) > 200:
        raise UserError(f"--name: {name!r} is not a Verilog module name (a letter or _, then "
                        f"letters, digits, _ or $; at most 200)")
    if name in _KEYWORDS:
        raise UserError(f"--name: {name!r} is a Verilog keyword; choose another module name")


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
    check_module_name(args.name)
    output = check_output_dir(args.output)
    try:
        clock_hz = parse_frequency(args.clock)
    except ValueError as error:
        raise UserError(f"--clock {args.clock}: {error}") from None
    try:
        baud = parse_baud(args.baud)
        period_cycles(clock_hz, DEFAULT_PRF_HZ)
        bit_cycles(clock_hz, baud)   # check before the top level is made
        top = FlissTop(clock_hz=int(clock_hz), baud=int(baud))
    except ValueError as error:
        raise UserError(str(error)) from None
    try:
        path = output / f"{args.name}.v"
        path.write_text(convert(top, args.name))
    except OSError as error:
        raise UserError(f"cannot write {args.output}: {error.strerror}") from None
    print(path)
