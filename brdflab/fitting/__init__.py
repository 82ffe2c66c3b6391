"""Levenberg–Marquardt fitting: sample sets, metrics, the fitter and stored fits."""
