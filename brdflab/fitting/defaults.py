"""The fitter's defaults, in one light module that the command line and the GUI both read
(no NumPy or SciPy import: `brdflab --help` stays fast)."""

DEFAULT_METRIC = "Ngan"
DEFAULT_RESTARTS = True
DEFAULTS_WHY = (
    "Defaults: --metric Ngan (Ngan et al. 2005: the cosine-weighted RMS over pairs with θi, θo ≤ 80°; "
    "plain L2 lets the specular peak of measured data dominate and leaves the rest of the lobe "
    "wrong) and --restarts (each model's own starting points are tried on a 60,000-sample "
    "subset first, which costs little and avoids poor local minima).")
