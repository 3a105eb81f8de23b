"""Quick start (README): fit one model from arrays, sweep a grid, hand the pick to scipy."""
import numpy as np, scipy.signal, oesweep

rng = np.random.default_rng(0)
u = np.repeat(rng.choice([-1.0, 1.0], 700), 3)                      # a binary input, N = 2100
y = scipy.signal.lfilter([0, 0.5, 0.3], [1, -1.2, 0.6], u) + 0.05 * rng.standard_normal(u.size)
y[rng.random(u.size) < 0.05] += 2.0                                 # 5 % spikes
model = oesweep.fit(u, y, nb=2, nf=2, k=0.5, ts=0.01)                 # least squares, then Huber
print(model, model.b, model.f)
np.savetxt("qs.csv", np.c_[u, y], delimiter=",", header="u,y", comments="")
run = oesweep.sweep({"name": "qs", "data": {"path": "qs.csv", "ts": 0.01}, "output": "qs-out",
                     "grid": {"nb": [1, 4], "nf": [1, 4], "k": [0.25, 0.5, 1.0]}}, progress=False)
print(run.cells.shape, run.selection["rule"], run.pick(), run.warnings)
sys = run.pick("rbic").to_scipy()                                      # scipy.signal.dlti, dt = ts
