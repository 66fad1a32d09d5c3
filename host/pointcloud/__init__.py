"""Depth frames as point clouds: where each pixel looks (:mod:`.geometry`), the points of a
run of frames (:mod:`.points`) and their files (PLY, PCD, LAS, MCAP for Foxglove), written run
by run (:mod:`.export`)."""
