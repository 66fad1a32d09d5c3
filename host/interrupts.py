"""Stops asked for by a signal, for loops that an exception may not reach.

``fliss`` turns Ctrl-C and ``kill`` (SIGTERM) into :exc:`KeyboardInterrupt` in the main thread
(:func:`fliss.host.commands.common.sigterm_interrupts`). Where the main thread waits inside a
library that runs Python code of its own at arbitrary times (Dask's garbage-collection hooks,
for one), the exception can be raised inside such code and swallowed there; the loop would then
go on. The signal handler also sets :data:`requested`, which such loops check between steps
(:func:`fliss.host.sweep.engine.compute`).
"""

import threading


__all__ = ["requested"]

#: Set by the signal handler when the user asked the command to stop; cleared when a command
#: installs the handler and when it takes it away.
requested = threading.Event()
