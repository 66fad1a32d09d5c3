"""``fliss generate``: the top level as Verilog in a folder with its FuseSoC core file, for users
who build with their own tools (:mod:`fliss.host.ip`)."""

import re
import sys

from ...hdl.clock import DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ, bit_cycles, period_cycles
from ...hdl.protocol import DEFAULT_BAUD
from ..errors import UserError
from ..ip import TB_MODES, DelayCheck, check_build, make_top, victim_period, write_folder
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
        help="write the FLISS top level as Verilog, with a FuseSoC core file (docs/verilog.md)",
        description="Writes a folder: NAME.v (module NAME with a clock `clk`, a synchronous "
                    "active-high reset `rst` and the pins of docs/ports.md), NAME.core (a "
                    "FuseSoC core: targets lint and sim), ports.md, constraints/ (a template "
                    "per board), blackboxes/ (with --fine-tdc) and testbench/ (a testbench "
                    "that sets a delay source over the UART and checks the laser's delays "
                    "against the model). Prints the path of each file, NAME.v first. The files an "
                    "earlier `fliss generate` wrote into the folder and this one does not (an "
                    "old testbench, a renamed module) are removed: DIR/.fliss-generated lists "
                    "what was written.")
    parser.add_argument("-o", "--output", default="build/verilog", metavar="DIR",
                        help="output folder")
    parser.add_argument("--clock", default=f"{DEFAULT_CLOCK_HZ // 1_000_000}MHz", metavar="HZ",
                        help="clock frequency of `clk`")
    parser.add_argument("--baud", default=f"{DEFAULT_BAUD // 1_000_000}M", metavar="BAUD",
                        help="UART baud rate (3M, 115200, ...)")
    parser.add_argument("--name", default="fliss_top", help="Verilog module name")
    variant = parser.add_mutually_exclusive_group()
    variant.add_argument("--small", action="store_true",
                         help="the iCEBreaker's smaller build (histograms only: docs/boards.md)")
    variant.add_argument("--fine-tdc", action="store_true",
                         help="with the fine TDC: ECP5 carry cells, declared in blackboxes/")
    parser.add_argument("--no-testbench", action="store_true",
                        help="leave out testbench/ and the core file's sim target")
    parser.add_argument("--tb-mode", default="masked", choices=TB_MODES,
                        help="delay source the testbench sets and checks")
    parser.add_argument("--tb-seed", type=lambda text: int(text, 0), default=0x5EED,
                        metavar="S", help="its seed (decimal or 0x hex)")
    parser.add_argument("--tb-length", type=int, default=6, metavar="L",
                        help="its register length (mseq)")
    parser.add_argument("--tb-mask-width", type=int, default=6, metavar="W",
                        help="its mask width (masked)")
    parser.add_argument("--tb-pulses", type=int, default=32, metavar="N",
                        help="laser pulses the testbench watches")
    parser.set_defaults(run=run)


def run(args):
    check_module_name(args.name)
    output = check_output_dir(args.output)
    try:
        clock_hz = parse_frequency(args.clock)
    except ValueError as error:
        raise UserError(f"--clock {args.clock}: {error}") from None
    variant = "small" if args.small else "fine" if args.fine_tdc else "full"
    try:
        # Every check before the top level is made (a top level left unused warns)
        baud = parse_baud(args.baud)
        period_cycles(clock_hz, DEFAULT_PRF_HZ)
        bit_cycles(clock_hz, baud)
        check_build(variant, name=args.name, clock_hz=clock_hz,
                    testbench=not args.no_testbench)
    except ValueError as error:
        raise UserError(str(error)) from None
    check = None
    if not args.no_testbench:
        check = DelayCheck(mode=args.tb_mode, length=args.tb_length,
                           mask_width=args.tb_mask_width, seed=args.tb_seed,
                           period=victim_period(clock_hz), pulses=args.tb_pulses)
        try:
            check.settings()
        except ValueError as error:
            raise UserError(f"the testbench's delay source (--tb-*): {error}") from None
    try:
        top = make_top(variant, clock_hz=int(clock_hz), baud=int(baud))
    except ValueError as error:
        raise UserError(str(error)) from None
    try:
        generated = write_folder(output, top, name=args.name, variant=variant, check=check)
    except ValueError as error:
        raise UserError(str(error)) from None
    except OSError as error:
        raise UserError(f"cannot write {args.output}: {error.strerror}") from None
    for path in generated.files:
        print(path)
    for path in generated.removed:
        print(f"fliss: note: removed {path}, written by an earlier `fliss generate` into this "
              f"folder", file=sys.stderr)
    for reason in generated.skipped:
        print(f"fliss: warning: left out {reason}", file=sys.stderr)
