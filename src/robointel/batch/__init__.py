"""Trials as tasks: in-process or on Ray, with a resumable Parquet result store.

>>> from robointel.batch import TaskSpec, run_batch, summarize
>>> specs = [TaskSpec("synthetic", s) for s in range(20)]
>>> run = run_batch(specs, "results/", progress=False)  # doctest: +SKIP
"""

from robointel.batch.engine import ENGINES, BatchRun, run_batch
from robointel.batch.execute import Fault, execute
from robointel.batch.registry import TrialKind, get_kind, kinds, register_kind
from robointel.batch.report import GroupSummary, plot_summary, summarize, wilson_interval
from robointel.batch.spec import TaskSpec, load_sweep, sweep_from_dict
from robointel.batch.store import SCHEMA, ResultStore

__all__ = ["ENGINES", "SCHEMA", "BatchRun", "Fault", "GroupSummary", "ResultStore", "TaskSpec", "TrialKind",
           "execute", "get_kind", "kinds", "load_sweep", "plot_summary", "register_kind", "run_batch", "summarize",
           "sweep_from_dict", "wilson_interval"]
