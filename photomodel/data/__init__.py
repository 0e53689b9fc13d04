"""The ground floor for data: the cache folder, files fetched by package name with checksums, array
files, cache keys made from the code that builds a result, and the generic mesh's source data.

Everything above it — the modeling core, the rig, the landmarks, tracking, the studio — reads data
through these modules; they import nothing of Face Studio but :mod:`photomodel.errors`.
:mod:`photomodel.samples` (the james scan, synthetic ground truth, the real clip) stands beside them
for tests, benchmarks and the sample project, and the core never imports it.
"""
