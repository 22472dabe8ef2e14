"""Linear combinations of parameters written as text: a base parameter ``pi_b = h @ pi`` read as
algebra (``"I_l1 + 0.0225 m_l1"``).

The one formatter of the project: the Delta's closed-form base set
(:func:`ident_hw.model.delta.closed_form_base`) and the base parameters found by SVD
(:mod:`ident_hw.identification.base_params`) name their rows with it, so the same combination
reads the same wherever it is shown.
"""

from __future__ import annotations

import numpy as np


def format_combination(row: np.ndarray, names, digits: int = 4) -> str:
    """``[1, 0.25]``, ``["m_l1", "m_l2"]`` → ``"m_l1 + 0.25 m_l2"``.

    ``row`` (n,) coefficients of the parameters ``names`` (n,); terms below 1e-10 of the largest
    are dropped, a coefficient of magnitude 1 is not written, the others with ``digits``
    significant digits."""
    terms: list[str] = []
    big = np.max(np.abs(row))
    for c, nm in zip(row, names):
        if abs(c) <= 1e-10 * big:
            continue
        mag = abs(c)
        text = nm if np.isclose(mag, 1.0, rtol=10.0 ** -(digits + 1), atol=0) else f"{mag:.{digits}g} {nm}"
        terms.append((" - " if c < 0 else " + ") + text if terms else ("-" if c < 0 else "") + text)
    return "".join(terms) if terms else "0"
