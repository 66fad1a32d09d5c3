"""``fliss ports``: the serial ports of this computer."""

from serial.tools import list_ports


__all__ = ["register", "run"]


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "ports", formatter_class=formatter, help="list serial ports",
        description="Lists the serial ports found on this computer, with their description and "
                    "USB ids: pass one to --port. A virtual board prints its own pty path; any "
                    "pyserial URL (socket://host:port, loop://) works too.")
    parser.add_argument("--all", action="store_true",
                        help="also list ports without a description (often on-board UARTs)")
    parser.set_defaults(run=run)


def run(args):
    ports = sorted(list_ports.comports(include_links=False), key=lambda port: port.device)
    if not args.all:
        ports = [port for port in ports if port.description and port.description != "n/a"]
    if not ports:
        print("no serial ports found" + ("" if args.all else " (try --all)"))
        return 0
    width = max(len(port.device) for port in ports)
    for port in ports:
        print(f"{port.device:<{width}}  {port.description}  {port.hwid}")
    return 0
