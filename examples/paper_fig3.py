"""FONS paper Fig. 3: the PV curve of actuator 1 sets the sequence.

Actuator 1 monotonic / peak-valley / hysteretic, actuator 2 monotonic,
negligible restrictors; a pump moves 1.8 mL/s in, pauses, and out again.
Saves fig3_C.png (volumes against time) and fig3_D.png (the V1-V2 path).

    python examples/paper_fig3.py
"""
from softflow import paper_scenes

paper_scenes.run_figure(3, physics="full")
