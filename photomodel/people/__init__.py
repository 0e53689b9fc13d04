"""Several people: seed 000's multilinear face model and seed 001's expression cloning."""
