"""Rate-aware calibration from recordings at several speeds: the per-record view, the fit,
its evaluation by phase and the floor set by the output's noise (docs/rate-calibration.md)."""
