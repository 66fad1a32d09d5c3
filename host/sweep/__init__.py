"""``fliss sweep``: independent simulation points on Dask.

* :mod:`.spec`: a TOML specification naming a point function and a grid of its parameters;
* :mod:`.engine`: the points run on a LocalCluster or a remote scheduler, into a table;
* :mod:`.figures`: figures drawn from the table's rows.
"""
