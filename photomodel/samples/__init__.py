"""Sample data and synthetic ground truth (menpo3d's james scan): tests, benchmarks and the sample project only."""
