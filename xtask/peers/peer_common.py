"""What the peer scripts share (imported from the scripts' own folder, which Python puts first
on the path when it runs one of them)."""

import contextlib
import os
import sys

import numpy as np


@contextlib.contextmanager
def stdout_to_stderr():
    """RichDEM prints progress and warnings on stdout (Python and C++): send file descriptor 1
    to stderr meanwhile so that stdout carries only the JSON object."""
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


def load_input(script, path, dtype):
    """The array in `path` (`.npy`), contiguous in `dtype`; `None` when the file is missing,
    after saying so on stderr and printing the empty JSON object `{}` (no timings)."""
    if not os.path.exists(path):
        print(f"{script}: {path} missing, no timings", file=sys.stderr)
        print("{}")
        return None
    return np.ascontiguousarray(np.load(path), dtype=dtype)
