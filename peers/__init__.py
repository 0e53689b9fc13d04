"""Peers: the comparison methods and the synthetic truth that benchmarks and tests measure ours against.

| module | holds |
|---|---|
| :mod:`peers.bundle_adjust` | full bundle adjustment with SciPy (what the paper contrasts its pose recovery with) |
| :mod:`peers.rigs` | synthetic heads and photo rigs with known cameras and points, accuracy against them |

Not part of the product: ``app``, ``photomodel`` and ``tracking`` never import this package.
``benchmarks/`` (speed and accuracy figures) and ``tests/`` import it by name; it is a package
of the project (``pyproject.toml``) so that neither needs a ``sys.path`` entry for it.
"""
