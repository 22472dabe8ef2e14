"""The results of a campaign: typed, frozen objects (:mod:`.objects`), the folder that stores them
(:mod:`.folder`), its ``STATUS`` line (:mod:`.status`) and the figures computed from them
(:mod:`.figures`). The runner, :func:`ident_hw.experiment.offline.identify` and the report share
these; the names below are those modules' own, gathered here for the callers."""

from .figures import (SETTLED, EstimatorSummary, Pair, ValidationFigures, estimator_summaries, metrics,
                      relative_residual_percent, settling_time, tracked, validation_figures)
from .folder import ResultsFile, load_fit, load_online, load_results, save_fit, save_online, save_results
from .objects import BaseFit, BaseRow, OnlineTrace, ParameterRow, ParameterTable, Results, TrajectoryFit, error_sigmas
from .status import STATUS_FILE, final_status, mark_status, read_status

__all__ = ["SETTLED", "EstimatorSummary", "Pair", "ValidationFigures", "estimator_summaries", "metrics",
           "relative_residual_percent", "settling_time", "tracked", "validation_figures", "ResultsFile", "load_fit",
           "load_online", "load_results", "save_fit", "save_online", "save_results", "BaseFit", "BaseRow",
           "OnlineTrace", "ParameterRow", "ParameterTable", "Results", "TrajectoryFit", "error_sigmas", "STATUS_FILE",
           "final_status", "mark_status", "read_status"]
