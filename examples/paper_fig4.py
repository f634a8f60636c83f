"""FONS paper Fig. 4: the restrictor between two plateau actuators sets the sequence.

A tight 2.5 mm ID tube / a Tesla valve (the tube's resistance from 1 to 2,
four times higher back) / a snapping valve (bursts on inflation, a tight
restrictor on deflation) between actuator 1 (lower plateau) and actuator 2.
Saves fig4_C.png and fig4_D.png.

    python examples/paper_fig4.py
"""
from softflow import paper_scenes as ps

results = []
for case in ps.FIG4_CASES:
    res, wall = ps.run(ps.fig4(case), 4)
    v1, v2 = ps.volumes(res)
    print(f"{case:9s}: {wall * 1e3:6.1f} ms, {res.stats['steps']} steps, "
          f"enclosed area {ps.enclosed_area(v1, v2) / ps.ML ** 2:+7.2f} mL^2")
    results.append(res)
print("saved", *ps.plot_panels(results, ps.FIG4_CASES, "Fig. 4", "fig4"))
