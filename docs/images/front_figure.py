"""Draws the README's figure, docs/images/fig5_three_fluids.png, with softflow:
the FONS paper's Fig. 5 network (a pump, two peak-valley actuators behind tight
tubes, a 100 mL accumulator on actuator 1) filled with air, water and ethylene
glycol, run at softflow's defaults (``softflow.paper_scenes``).

    python docs/images/front_figure.py
"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from softflow import paper_scenes  # noqa: E402

ML = 1e-6
OUT = Path(__file__).resolve().parent / "fig5_three_fluids.png"


def main(path=OUT):
    fig, (ax_t, ax_path) = plt.subplots(1, 2, figsize=(9.0, 3.6),
                                        gridspec_kw={"width_ratios": [1.6, 1]})
    for (label, system), color in zip(paper_scenes.figure(5), ("C0", "C1", "C2")):
        result, _ = paper_scenes.run(system, 5)
        v1, v2 = paper_scenes.volumes(result)
        ax_t.plot(result.times, v1 / ML, color=color, label=f"{label}: actuator 1")
        ax_t.plot(result.times, v2 / ML, color=color, ls="--", label=f"{label}: actuator 2")
        ax_path.plot(v1 / ML, v2 / ML, color=color, label=label)
    ax_t.set(xlabel="time [s]", ylabel="actuator volume [mL]",
             title="pump in, pause, pump out")
    ax_path.set(xlabel="actuator 1 volume [mL]", ylabel="actuator 2 volume [mL]",
                title="the inflation sequence")
    ax_t.legend(fontsize=7, ncol=1, loc="upper left")
    ax_path.legend(fontsize=7, loc="lower right")
    fig.suptitle("The FONS paper's Fig. 5 network with air, water and ethylene glycol",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


if __name__ == "__main__":
    print("saved", main())
