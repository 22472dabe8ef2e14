"""The MATLAB export of a results folder (``results.mat``, :func:`scipy.io.savemat`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.io

from ident_hw.results import Results


def save_mat(path: Path, results: Results) -> None:
    """Parameters (physical and base), fits and online estimates as MATLAB structs."""
    p = results.parameters
    doc = {
        "parameter_names": np.array(p.names, dtype=object),
        "initial": p.initial, "identified": p.identified, "sigma": p.sigma,
        "lower": p.lower, "upper": p.upper,
        "fits": {f.name.replace("-", "_"): {"role": f.role, "t": f.t, "tau": f.tau, "tau_model": f.tau_model,
                                             "Theta": f.Theta, **({"X": f.X} if f.X is not None else {}),
                                             **({"tau_base": f.tau_base} if f.tau_base is not None else {})}
                 for f in results.fits},
    }
    if results.base_fit is not None:
        b = results.base_fit
        doc["base_fit"] = {"expressions": np.array(b.expressions, dtype=object), "H": b.H, "identified": b.coef,
                           "sigma": b.sigma, "initial": b.initial, **({"truth": b.truth} if b.truth is not None else {})}
    if p.truth is not None:
        doc["truth"] = p.truth
    if results.online is not None:
        doc["online"] = {"names": np.array(results.online.names, dtype=object), "t": results.online.t,
                         **{f"estimates_{k.replace(' ', '_').replace('-', '_')}": v
                            for k, v in results.online.estimates.items()}}
    scipy.io.savemat(path, doc, do_compression=True, long_field_names=True)
