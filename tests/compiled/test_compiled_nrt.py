"""The compiled kernels' helpers and model functions run without numba's reference counting
(``_nrt=False``, see ``ldaspark.compiled.kernels``): every array a kernel allocates must still be
freed. numba's runtime counts allocations and frees when NUMBA_NRT_STATS=1 is set before it
starts, so the check runs in a child process."""
import json
import os
import subprocess
import sys

CHILD = r"""
import json, sys
import numpy as np
import numba
from numba.core.runtime import rtsys
from ldaspark.compiled.fast import fast_integrate
from ldaspark.models.scenes import get_scene

def counts():
    st = rtsys.get_allocation_stats()
    return np.array([st.alloc, st.free, st.mi_alloc, st.mi_free])

out = {}
# spark_run (mechanical), general_run with a nonideal term (views of the workspace), lf2_run
for name, method in (("particle", "gauss-2"), ("friction-skate", "gauss-2"),
                     ("mp-particles", "lobatto-iiia-iiib-2")):
    sc = get_scene(name)
    fast_integrate(sc, method, h=0.01, n_steps=10, every=1)
    a = counts()
    for _ in range(20):
        fast_integrate(sc, method, h=0.01, n_steps=10, every=1)
    out[name] = (counts() - a).tolist()

# negative control: arrays that outlive their call (here held in a list, as a leaked
# workspace would be held by a stray reference) show up as allocations without frees
@numba.njit
def make(n):
    return np.zeros(n)

make(3)
a = counts()
kept = [make(3) for _ in range(20)]
out["control"] = (counts() - a).tolist()
print(json.dumps(out))
"""


def test_kernels_free_every_array_they_allocate():
    env = dict(os.environ, NUMBA_NRT_STATS="1")
    r = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    for name in ("particle", "friction-skate", "mp-particles"):
        alloc, free, mi_alloc, mi_free = out[name]
        assert alloc > 0 and mi_alloc > 0, (name, out[name])       # the runs did allocate
        assert (alloc, mi_alloc) == (free, mi_free), (name, out[name])
    alloc, free, mi_alloc, mi_free = out["control"]
    assert alloc == 20 and free == 0 and mi_alloc == 20 and mi_free == 0, out["control"]
