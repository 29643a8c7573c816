"""Design studies: sweep or optimise the operating point and the mill's design (``millctl study``).

A study file (:mod:`.schema`) names the base mill, the parameters to vary,
the metrics (:mod:`.metrics`), the constraints and the objective. Points run
through one adapter to the physics (:mod:`.engine`) on a backend
(:mod:`.backends`: this process, local cores, or Dask), are kept in a results
file that a rerun resumes (:mod:`.store`), and are summarised and drawn
(:mod:`.run`, :mod:`.figures`). docs/studies.md is the user's guide.
"""

from millctl.studies.backends import DaskBackend, LocalBackend, SerialBackend, make_backend
from millctl.studies.engine import PointTask, evaluate, evaluate_batch
from millctl.studies.metrics import DEFAULT_METRICS, METRICS
from millctl.studies.run import StudyResult, StudyRunner, check_parameters, grid_points, pareto_front
from millctl.studies.schema import Study, StudyError, load_study
from millctl.studies.store import ResultsStore

__all__ = [
    "DEFAULT_METRICS",
    "METRICS",
    "DaskBackend",
    "LocalBackend",
    "PointTask",
    "ResultsStore",
    "SerialBackend",
    "Study",
    "StudyError",
    "StudyResult",
    "StudyRunner",
    "check_parameters",
    "evaluate",
    "evaluate_batch",
    "grid_points",
    "load_study",
    "make_backend",
    "pareto_front",
]
