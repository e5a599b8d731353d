"""Drape a cloth on a ball and plot how high it is: python drape_height.py [OUT.png]"""
import sys

import cloth


def drape(duration_s=1.0, particles=21):
    """Times (s), lowest and highest particle heights (m) of the drape fixture."""
    overrides = {"panels.0.particles": [particles, particles], "simulation.duration_s": duration_s}
    scene = cloth.Scene.from_toml("fixtures/scenes/drape-sphere.toml", overrides)
    sim, rows = scene.simulation(), []
    for _ in range(round(scene.duration_s / scene.dt_s)):
        sim.step()
        z = sim.positions[:, 2]
        rows.append((sim.time_s, z.min(), z.max()))
    return rows


if __name__ == "__main__":
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, low, high = zip(*drape())
    plt.plot(t, high, label="highest")
    plt.plot(t, low, label="lowest")
    plt.xlabel("time (s)")
    plt.ylabel("height (m)")
    plt.legend()
    plt.savefig(sys.argv[1] if len(sys.argv) > 1 else "drape-height.png")
