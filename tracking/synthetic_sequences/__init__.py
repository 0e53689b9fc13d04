"""Ground truth for tracking: sample expressions of the scan, the sample video, the fitted sample."""
