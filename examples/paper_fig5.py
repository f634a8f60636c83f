"""FONS paper Fig. 5: the same network filled with air, water or ethylene glycol.

Two peak-valley actuators (1's peak slightly higher, its valley much lower),
tight tubes and a 100 mL accumulator; the fluid is the only difference.
Saves fig5_C.png and fig5_D.png.

    python examples/paper_fig5.py
"""
from softflow import paper_scenes

paper_scenes.run_figure(5, physics="full")
