"""Preprocessing: world transform, crop, background subtraction, outlier removal."""
