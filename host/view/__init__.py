"""The live view: a web page that shows what a board sends (or what a capture file holds),
frame by frame, in any number of browsers (``fliss view``, ``fliss capture --view``;
docs/view.md).

* :mod:`.feed`: the :class:`~.feed.Feed` an acquisition hands every item it receives, without
  waiting, and the pictures and rates the pages draw from it;
* :mod:`.document`: the page, a Bokeh document per browser;
* :mod:`.server`: Bokeh's server on a thread of its own (:class:`~.server.ViewServer`);
* :mod:`.live`: a board watched without a file (:func:`~.live.watch`);
* :mod:`.replay`: a capture file played back (:class:`~.replay.Replay`).

Only :mod:`.document` and :mod:`.server` import Bokeh (the ``view`` extra).
"""
