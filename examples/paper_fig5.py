"""FONS paper Fig. 5: the same network filled with air, water or ethylene glycol.

Two peak-valley actuators (1's peak slightly higher, its valley much lower),
tight tubes and a 100 mL accumulator; the fluid is the only difference.
Saves fig5_C.png and fig5_D.png.

    python examples/paper_fig5.py
"""
import softflow as sf
from softflow import paper_scenes as ps

results = []
for fluid in (sf.air, sf.water, sf.ethylene_glycol):
    res, wall = ps.run(ps.fig5(fluid), 5)
    v1, v2 = ps.volumes(res)
    print(f"{fluid.name:16s}: {wall * 1e3:6.1f} ms, {res.stats['steps']} steps, "
          f"enclosed area {ps.enclosed_area(v1, v2) / ps.ML ** 2:+7.2f} mL^2")
    results.append(res)
print("saved", *ps.plot_panels(results, ps.FIG5_FLUIDS, "Fig. 5", "fig5"))
