"""Reads the metadata attribute of an HDF5 result file of the earlier format, in a child process.

Earlier versions stored the metadata as a variable-length string attribute; it lives in the
file's global heap, and one corrupt heap entry makes the HDF5 library loop forever inside the
read, out of reach of any check in Python. ``load_result`` therefore reads such an attribute
here, in a child process given the open file's descriptor, and ends the child after a time
bound: a damaged legacy file is an error, not a hang. Files of the current format (a scalar
dataset of one fixed-length string) never come here.

Run as ``python -m ldaspark.core.h5legacy FD`` (``read_legacy_metadata`` starts it with ``-c`` and
``lifecycle.python_code``: nothing imported from the working directory): prints the attribute's
text on stdout.
"""
from __future__ import annotations

import os
import subprocess
import sys

from .errors import InputError

#: seconds for the child (importing h5py is most of it); a healthy file reads in well under 1 s
TIMEOUT = 60.0
#: the attribute of the earlier writer held at most this many bytes
MAX_BYTES = 2 ** 20


def read_legacy_metadata(fh) -> str:
    """The metadata attribute of the open legacy HDF5 file ``fh`` (a binary file object), read
    by a child process with a time bound."""
    from .lifecycle import python_code, run_linked     # the child dies with this process
    fd = fh.fileno()
    # -c with python_code, not -m: nothing is imported from the working directory
    code = python_code("from ldaspark.core.h5legacy import main\nsys.exit(main(sys.argv[1:]))")
    try:
        proc = run_linked([sys.executable, "-c", code, str(fd)], pass_fds=(fd,),
                          stdin=subprocess.DEVNULL, capture_output=True, timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        raise InputError(f"the metadata attribute of this earlier-format HDF5 file was not read within "
                         f"{TIMEOUT:.0f} s (a damaged file)") from None
    if proc.returncode != 0:
        last = (proc.stderr.decode("utf-8", "replace").strip().splitlines() or ["no message"])[-1]
        raise InputError(f"the metadata attribute of this earlier-format HDF5 file is unreadable: {last[:200]}")
    if len(proc.stdout) > MAX_BYTES:
        raise InputError("the metadata attribute is longer than 1 MiB")
    try:
        return proc.stdout.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError("the metadata attribute is not UTF-8 text") from None


def main(argv=None) -> int:
    import h5py
    fd = int((argv or sys.argv[1:])[0])
    with os.fdopen(fd, "rb", closefd=False) as raw:
        raw.seek(0)
        with h5py.File(raw, "r") as f:
            if "metadata" not in f.attrs:
                print("no metadata attribute", file=sys.stderr)
                return 1
            aid = f.attrs.get_id("metadata")
            dt = aid.dtype
            is_str = dt.kind in "SU" or h5py.check_string_dtype(dt) is not None
            if not is_str or aid.shape not in ((), None) or aid.get_storage_size() > MAX_BYTES:
                print("the metadata attribute is not a JSON string of at most 1 MiB", file=sys.stderr)
                return 1
            val = f.attrs["metadata"]
    if isinstance(val, bytes):
        val = val.decode("utf-8")
    if not isinstance(val, str):
        print("the metadata attribute is not a string", file=sys.stderr)
        return 1
    sys.stdout.write(val)
    return 0


if __name__ == "__main__":
    sys.exit(main())
