"""The reproduction of section 6: the experiments run, the report and the figures written."""

import os
import sys

from .experiments import run_experiments
from .figures import figures as draw_figures
from .report import rows as result_rows, write_csv, write_markdown


__all__ = ["reproduce"]


def reproduce(config, out_dir, *, workers=1, figures=True, stream=sys.stderr, scheduler=None):
    """Run the reproduction; write CSV, Markdown and PNG files into ``out_dir``.

    The settings run on the sweep engine: ``workers`` local Dask workers, or the Dask
    ``scheduler`` (``"tcp://HOST:PORT"``) given.

    Returns the list of result rows (dicts), one per setting. Raises
    :class:`~fliss.host.reproduce.experiments.ReproductionError` if the victim's peak is missing
    from a reference run.
    """
    config.check()
    by_t, results, elapsed = run_experiments(config, workers=workers, stream=stream,
                                             scheduler=scheduler)
    os.makedirs(out_dir, exist_ok=True)
    rows = result_rows(config, by_t, results)
    write_csv(os.path.join(out_dir, "results.csv"), rows)
    written = ["results.csv", "results.md"]
    if figures:
        written += draw_figures(config, by_t, results, out_dir)
    write_markdown(os.path.join(out_dir, "results.md"), config, rows, by_t, results, elapsed,
                   workers, written)
    return rows
