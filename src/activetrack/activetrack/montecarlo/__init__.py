"""The one parallel Monte Carlo of the library: :func:`parallel_map` runs every task with its
own seed on local forked processes (:mod:`.local`) or on the workers of a Dask cluster
(:mod:`.dask`), in the same chunks (:mod:`.chunks`), bit-identical whichever runs them."""

from activetrack.montecarlo.chunks import CHUNKS_PER_WORKER, even_chunks
from activetrack.montecarlo.dask import Scheduler
from activetrack.montecarlo.local import available_jobs
from activetrack.montecarlo.parallel import Progress, TaskProgress, check_jobs, parallel_map

__all__ = [
    "CHUNKS_PER_WORKER",
    "Progress",
    "Scheduler",
    "TaskProgress",
    "available_jobs",
    "check_jobs",
    "even_chunks",
    "parallel_map",
]
