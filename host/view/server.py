"""The live view's web server: Bokeh's server (Tornado) on a thread of its own, serving one
page, a Bokeh document per browser session (:mod:`.document`), all drawn from one
:class:`~fliss.host.view.feed.Feed`.

The port is bound in the caller's thread, so that a port in use is refused at once, before
any board is touched; the server's thread then runs its own event loop until :meth:`ViewServer.close`.
"""

import asyncio
import errno
import logging
import threading
import time

from ..errors import ViewError
from .feed import Feed


__all__ = ["DEFAULT_PORT", "PERIOD_S", "ViewServer"]

_logger = logging.getLogger(__name__)

#: The view's TCP port unless told otherwise (Bokeh's own default).
DEFAULT_PORT = 5006

#: Seconds between two updates of a page.
PERIOD_S = 0.05

#: Milliseconds after which a session without a page is forgotten (its updates stop); more
#: than a slow page takes to load and connect.
_FORGET_MS = 3000

#: Milliseconds between two counts of the pages connected.
_COUNT_MS = 200


class ViewServer:
    """Serve the view of ``feed`` at ``http://address:port/`` (port 0: any free port).

    ``notify``, if given, is called (from the server's thread) with one line when a browser
    opens the page and when one leaves it (closes the tab, goes elsewhere, or is cut off).
    Use it in a ``with`` block, or call :meth:`close`.

    Raises
    ------
    ViewError
        The port is in use or cannot be bound, or the server does not start.
    """

    def __init__(self, feed: Feed, *, port: int = DEFAULT_PORT, address: str = "localhost",
                 notify=None, period_s: float = PERIOD_S):
        from bokeh.server.util import bind_sockets

        if not 0 <= port < 65536:
            raise ViewError(f"the view's port must be 0 to 65535, not {port}")
        self.feed, self.address, self.period_s = feed, address, period_s
        for name in ("bokeh", "tornado"):
            # A page closed in the middle of an update is no news (tab closed: see notify).
            logger = logging.getLogger(name)
            if logger.level == logging.NOTSET:
                logger.setLevel(logging.ERROR)
        self._notify = notify or (lambda line: None)
        try:
            self._sockets, self.port = bind_sockets(address, port)
        except OSError as error:
            if error.errno == errno.EADDRINUSE:
                raise ViewError(f"port {port} on {address} is in use (another fliss view?): "
                                f"give another with --view-port, or 0 for any free port") \
                    from None
            raise ViewError(f"cannot serve the view on {address}:{port}: "
                            f"{error.strerror or error}") from None
        #: Pages open (connected) now.
        self.watching = 0
        self._flows = {}
        self._loop = None
        self._error = None
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="fliss-view", daemon=True)
        self._thread.start()
        self._ready.wait(30)
        if self._error is not None or self._loop is None:
            self.close()
            raise ViewError(f"the view's server did not start: {self._error or 'timeout'}")

    @property
    def url(self) -> str:
        """The page's address."""
        return f"http://{self.address}:{self.port}/"

    def _serve(self):
        try:
            from bokeh.application import Application
            from bokeh.application.handlers.document_lifecycle import DocumentLifecycleHandler
            from bokeh.application.handlers.function import FunctionHandler
            from bokeh.server.server import BaseServer
            from bokeh.server.tornado import BokehTornado
            from tornado.httpserver import HTTPServer
            from tornado.ioloop import IOLoop, PeriodicCallback

            asyncio.set_event_loop(asyncio.new_event_loop())
            loop = IOLoop.current()
            hosts = {self.address, "localhost", "127.0.0.1"}
            # (the second handler runs the documents' on_session_destroyed callbacks)
            application = Application(FunctionHandler(self._document),
                                      DocumentLifecycleHandler())
            tornado = BokehTornado(
                {"/": application},
                extra_websocket_origins=[f"{host}:{self.port}" for host in sorted(hosts)],
                check_unused_sessions_milliseconds=_FORGET_MS,
                unused_session_lifetime_milliseconds=_FORGET_MS)
            http = HTTPServer(tornado)
            http.add_sockets(self._sockets)
            server = BaseServer(loop, tornado, http)
            server.start()
            self._tornado = tornado
            PeriodicCallback(lambda: self._count(tornado), _COUNT_MS).start()
        except Exception as error:      # noqa: BLE001 -- said by the caller's thread
            self._error = f"{type(error).__name__}: {error}"
            self._ready.set()
            return
        self._loop = loop
        self._ready.set()
        try:
            loop.start()
        finally:
            server.stop(wait=False)
            loop.close(all_fds=True)

    def _document(self, doc):
        from .document import build_document

        flow = build_document(doc, self.feed, self.period_s, self._notify)
        self._flows[id(doc)] = flow
        doc.on_session_destroyed(lambda context: self._flows.pop(id(doc), None))

    def pages(self):
        """``(updates sent, updates missed, behind)`` of each page's session now (see
        :class:`~fliss.host.view.document.PageFlow`); a session outlives its page by a few
        seconds."""
        return [(flow.updates, flow.missed, flow.behind) for flow in list(self._flows.values())]

    def _count(self, tornado):
        # Pages connected now (a session's websocket): an HTTP request alone is no browser.
        watching = sum(session.connection_count for session in tornado.get_sessions("/"))
        while self.watching != watching:
            opened = watching > self.watching
            self.watching += 1 if opened else -1
            self._notify(f"a browser {'opened' if opened else 'left'} the page "
                         f"({self.watching} watching)")

    def close(self) -> None:
        """Stop serving; pages still open get one more update (the source's end) first,
        then stop updating."""
        loop, self._loop = self._loop, None
        if loop is not None:
            if self.watching:
                time.sleep(2 * self.period_s)
            loop.add_callback(loop.stop)
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(10)
        for sock in getattr(self, "_sockets", ()):
            sock.close()

    def __enter__(self) -> "ViewServer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
