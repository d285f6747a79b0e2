"""Run one job (`estimate`, `diagnose`, or any picklable callable) over many logs, locally or on a Ray cluster.

`run_batch` is the engine of `cartpush batch` (see docs/batch.md): one JSON line per log,
written as each finishes, resumable, on joblib processes or Ray tasks with the same code path.
"""

from cartpush.batch.engine import (
    BatchError,
    CommandJob,
    OutputPathError,
    check_output,
    done_paths,
    expand_inputs,
    run_batch,
)

__all__ = ["BatchError", "CommandJob", "OutputPathError", "check_output", "done_paths", "expand_inputs", "run_batch"]
