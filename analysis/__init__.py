"""Analysis of TCSPC histograms shared by the models and the host: :mod:`.peaks`, the peak finder."""
