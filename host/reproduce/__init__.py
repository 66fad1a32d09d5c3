"""``fliss reproduce``: the experiments of section 6 of the paper on the scene simulator.

* :mod:`.experiments`: the paper's settings and the points they run;
* :mod:`.report`: result rows, CSV and Markdown tables beside the paper's;
* :mod:`.figures`: figures in the spirit of the paper's Figures 7 to 12;
* :mod:`.run`: :func:`~.run.reproduce`, the three together on Dask.
"""
