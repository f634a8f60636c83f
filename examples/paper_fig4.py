"""FONS paper Fig. 4: the restrictor between two plateau actuators sets the sequence.

A tight 2.5 mm ID tube / a Tesla valve (the tube's resistance from 1 to 2,
four times higher back) / a snapping valve (bursts on inflation, a tight
restrictor on deflation) between actuator 1 (lower plateau) and actuator 2.
Saves fig4_C.png and fig4_D.png.

    python examples/paper_fig4.py
"""
from softflow import paper_scenes

paper_scenes.run_figure(4, physics="full")
