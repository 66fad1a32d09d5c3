"""The live view: a web page that shows what a board sends (or a capture file held), frame by
frame, in any number of browsers, drawn by Bokeh's server."""
