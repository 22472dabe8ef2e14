"""Config sections → what the identification works with: the filter settings of a recording
(:class:`ident_hw.filtering.FilterSettings`), a step's parameter names, and the parameter scales of
the online estimators and of the physically consistent step (:mod:`ident_hw.config.scales`)."""

from __future__ import annotations

import dataclasses
import fnmatch
from typing import Any

from ident_hw.filtering import FilterSettings

from .identification import FilterConfig, OnlineConfig, PhysicalConfig, StepConfig
from .scales import parameter_scales


def filter_settings(filter: FilterConfig, sample_rate: float, bandwidth: float | None = None,
                    position_margin: float = 1.0) -> FilterSettings:
    """The filter settings for data sampled at ``sample_rate`` (Hz), for a motion of ``bandwidth``
    Hz (default ``filter.bandwidth``) whose positions are low-passed ``position_margin`` times
    above the band (:attr:`ident_hw.filtering.FilterSettings.position_cutoff_hz`); ``cutoff`` and
    ``decimation`` override the defaults of :meth:`ident_hw.filtering.FilterSettings.for_sample_rate`."""
    base = FilterSettings.for_sample_rate(sample_rate, bandwidth or filter.bandwidth, filter.order)
    overrides: dict[str, Any] = {k: v for k, v in (("cutoff_hz", filter.cutoff), ("decimation", filter.decimation)) if v is not None}
    return dataclasses.replace(base, position_margin=position_margin, **overrides)


def step_parameters(step: StepConfig, names: tuple[str, ...]) -> tuple[str, ...]:
    """A step's parameters among the model's ``names``, in the model's order where a pattern
    (``*``, ``?``, ``[...]``) names several (``[all]``: every one); a name that is neither a
    parameter nor a pattern matching one stays as it is (the config check refuses it)."""
    if step.parameters == ("all",):
        return tuple(names)
    out: list[str] = []
    for entry in step.parameters:
        matched = [n for n in names if fnmatch.fnmatchcase(n, entry)] if entry not in names else [entry]
        for name in matched or [entry]:
            if name not in out:
                out.append(name)
    return tuple(out)


def online_scales(online: OnlineConfig, names, cad) -> tuple[float, ...]:
    """(n,) the online estimators' scale of every parameter ``names`` (n,) with CAD values ``cad``
    (:func:`ident_hw.config.scales.parameter_scales`)."""
    return parameter_scales(names, cad, online.scales, "identification.online.scales")


def physical_scales(physical: PhysicalConfig, names, cad) -> tuple[float, ...]:
    """(n,) the consistent step's prior scale of every parameter ``names`` (n,) with CAD values
    ``cad`` (:func:`ident_hw.config.scales.parameter_scales`)."""
    return parameter_scales(names, cad, physical.scales, "identification.physical.scales")
