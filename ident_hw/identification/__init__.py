"""Identification of the dynamic parameters from a regressor ``Y`` (N, k, n) and forces ``tau`` (N, k)."""
