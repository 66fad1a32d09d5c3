"""Analysis shared by the models and the host: :mod:`.peaks`, the peak finder of TCSPC
histograms; :mod:`.calibration`, the code-density calibration of a tapped-delay-line TDC."""
