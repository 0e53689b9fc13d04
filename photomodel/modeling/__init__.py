"""The modeling stage (§5.1): cameras from clicks, the generic mesh deformed by RBF, refinement."""
