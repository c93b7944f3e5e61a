#!/usr/bin/env bash
# Issue 31's GPU run, as one prepared script (a device machine is lent for
# minutes): checks the Pallas kernel on the GPU against the numba batch, then
# runs benchmarks/bench_ensemble.py (the table of docs/performance.md) and the
# jax tests on the GPU. Every log goes to OUTDIR.
#
#     bash benchmarks/gpu_ensemble.sh OUTDIR [COMMIT]
#
# Run from the repository root with rk4h importable. If the Pallas kernel fails
# on the GPU (or jax has no Pallas Triton backend, which rk4h would replace
# by jax's loops with a warning: an error here), the table is measured with
# jax's own loops (xla) and the smoke log says why; nothing falls back
# silently.
set -uo pipefail
out=${1:?usage: gpu_ensemble.sh OUTDIR [COMMIT]}
commit=${2:-unknown}
mkdir -p "$out" || exit 2
export PYTHONUNBUFFERED=1 PYTHONDONTWRITEBYTECODE=1
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv 2>&1 | tee "$out/env.txt"
python3 -c "import jax, numba, numpy, scipy, rk4h; print('jax', jax.__version__, jax.devices(), 'numba', numba.__version__, 'numpy', numpy.__version__, 'scipy', scipy.__version__, rk4h.__file__)" 2>&1 | tee -a "$out/env.txt"

kernels="xla:1 xla:16"
jk=xla
# -W error: rk4h's warning that it fell back to jax's loops (no Pallas Triton) fails the check
if timeout 100 python3 -W "error:rk4h.ensemble:RuntimeWarning" - <<'PY' 2>&1 | tee "$out/smoke.log"
import sys
import time
import numpy as np
import rk4h
from rk4h.batch import _jax
sys.path.insert(0, "benchmarks")
from bench_ensemble import MASSES, SPRINGS, rel_diff
model = rk4h.make_model("chain", {"masses": MASSES, "springs": SPRINGS})
rng = np.random.default_rng(9)
B, h = 1000, 1e-3
y0 = rng.uniform(-0.005, 0.005, (B, 4))
masses = rng.uniform(0.3, 4.0, (B, 2))
worst = 0.0
for method in ["rk4", "stormer-verlet", "yoshida4"]:
    kw = dict(h=h, method=method, params={"masses": masses}, t_eval=[0.0, 0.777, 2.0])
    ref = rk4h.ensemble(model, y0, (0.0, 2.0), backend="numba", **kw).y
    for dtype in ["float64", "float32"]:
        t = time.perf_counter()
        r = rk4h.ensemble(model, y0, (0.0, 2.0), backend="jax", dtype=dtype, **kw)
        t = time.perf_counter() - t
        d = rel_diff(r.y, ref)
        print(f"pallas on {_jax.jax.default_backend()}: {method} {dtype}: {t:.1f} s, status all 0: "
              f"{bool((r.status == 0).all())}, relative difference from numba {d:.1e}", flush=True)
        if dtype == "float64":
            worst = max(worst, d)
assert _jax.KERNEL[_jax.jax.default_backend()] == "pallas"
assert worst <= 1e-13, worst
PY
then
    kernels="$kernels pallas:64 pallas:128 pallas:256"
    jk=pallas
fi
echo "main table's kernel: $jk; sweep: $kernels" | tee -a "$out/smoke.log"

timeout 270 python3 benchmarks/bench_ensemble.py --sizes 1 1e3 1e5 1e6 --work 1e9 --min-steps 1000 \
    --max-steps 1e5 --repeats 3 --jax-kernel "$jk" --kernels $kernels --kernel-steps 1e4 \
    --chains 1e5 1e6 1e7 --chain-steps 20 --diffrax 1e3 1e5 --commit "$commit" \
    --docs docs/performance.md 2>&1 | tee "$out/bench.log"
cp docs/performance.md "$out/performance.md"
timeout 90 python3 -m pytest -p no:randomly -p no:cacheprovider -q -n 0 tests/test_ensemble.py \
    tests/test_bench_ensemble.py -k "jax or kernel" 2>&1 | tee "$out/pytest.log" | tail -25
