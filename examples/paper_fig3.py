"""FONS paper Fig. 3: the PV curve of actuator 1 sets the sequence.

Actuator 1 monotonic / peak-valley / hysteretic, actuator 2 monotonic,
negligible restrictors; a pump moves 1.8 mL/s in, pauses, and out again.
Saves fig3_C.png (volumes against time) and fig3_D.png (the V1-V2 path).

    python examples/paper_fig3.py
"""
from softflow import paper_scenes as ps

results = []
for case in ps.FIG3_CASES:
    res, wall = ps.run(ps.fig3(case), 3)
    v1, v2 = ps.volumes(res)
    print(f"{case:12s}: {wall * 1e3:6.1f} ms, {res.stats['steps']} steps, "
          f"enclosed area {ps.enclosed_area(v1, v2) / ps.ML ** 2:+7.2f} mL^2")
    results.append(res)
print("saved", *ps.plot_panels(results, ps.FIG3_CASES, "Fig. 3", "fig3"))
