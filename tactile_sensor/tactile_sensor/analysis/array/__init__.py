"""Module arrays: aligning several channels with a wrench reference, and fitting the array
calibration from them (docs/array.md)."""
