"""The paper's two scenarios through FMPy: CSV results, plots in the spirit of the paper's
figures 2-5, and an animation of the linkage; with the FMI 3.0 archive, a change-point
linkage going on through its change point on either branch. Run by `cargo xtask demo`:

    python examples/demo.py target/fmu/CyclicMechanism.fmu target/demo \
        target/fmu/CyclicMechanism-fmi3.fmu
"""

import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import fmpy  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from fmpy.util import write_csv  # noqa: E402
from matplotlib.animation import FuncAnimation, PillowWriter  # noqa: E402

# The paper's motor and load laws [79], [80], as the FMU's built-in-law parameters.
PAPER_LAWS = dict(Mm_a0=100.0, Mm_a1=-20.0, Mm_a2=-1.0, Mr_b0=20.0, Mr_b1=-0.05)
CASES = {"case1": dict(PAPER_LAWS), "case2": dict(PAPER_LAWS, k34=40.0)}
NON_GRASHOF = dict(l=0.4, l2=0.3, l3=0.35, L=0.5, phi2_0=1.0)
TITLES = {"case1": "Case 1: k12 = k34 = 100 N·m/rad", "case2": "Case 2: k12 = 100, k34 = 40 N·m/rad"}


def simulate(fmu, start_values, stop_time=10.0, step=1e-3):
    # Tolerance 1e-10, as in the README's snippet: the 8 printed decimals are then those
    # published (at the default 1e-8 the last one can differ).
    return fmpy.simulate_fmu(fmu, start_values=start_values, stop_time=stop_time,
                             output_interval=step, relative_tolerance=1e-10)


def plot_pair(result, names, title, path):
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, style in zip(names, ("-", "--")):
        ax.plot(result["time"], result[name], style, label=name.replace("phi", "φ"))
    ax.set(xlabel="time (s)", ylabel="angle (rad)", title=title)
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_overview(results, path):
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
    for column, (case, result) in enumerate(results.items()):
        for row, names in enumerate((("phi1", "phi2"), ("phi3", "phi4"))):
            ax = axes[row, column]
            for name, style in zip(names, ("-", "--")):
                ax.plot(result["time"], result[name], style, label=name.replace("phi", "φ"))
            ax.set(ylabel="angle (rad)", title=TITLES[case] if row == 0 else None)
            ax.grid(True, alpha=0.3)
            ax.legend(loc="upper left")
        axes[1, column].set_xlabel("time (s)")
    fig.suptitle("CyclicMechanism FMU through FMPy: the paper's two cases (figs. 2–5)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_speeds_and_twists(results, path):
    """What φ1..φ4 hide: the motor's spin-up and the loop's speeds (top), and the springs'
    twists φ1 − φ2 and φ3 − φ4 (bottom), for both cases."""
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True, sharey="row")
    for column, (case, result) in enumerate(results.items()):
        t = result["time"]
        top, bottom = axes[0, column], axes[1, column]
        for k, colour in zip(range(1, 5), ("tab:green", "tab:blue", "tab:orange", "tab:red")):
            top.plot(t, result[f"omega{k}"], color=colour, lw=1, label=f"ω{k}")
        top.set(ylabel="speed (rad/s)", title=TITLES[case])
        bottom.plot(t, result["phi1"] - result["phi2"], color="tab:blue", lw=1, label="φ1 − φ2 (spring k12)")
        bottom.plot(t, result["phi3"] - result["phi4"], color="tab:red", lw=1, label="φ3 − φ4 (spring k34)")
        bottom.set(ylabel="twist (rad)", xlabel="time (s)")
        for ax in (top, bottom):
            ax.grid(True, alpha=0.3)
    # One legend per row, outside the data, on the right.
    for row in range(2):
        axes[row, 1].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9)
    fig.suptitle("Speeds and spring twists: the spin-up, the rocker's swing, the springs at work")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def animate_linkage(result, path, title, duration=3.0, fps=25, l=0.5, l2=0.05, l3=0.5):
    """Crank O2A2, rod A2A3, rocker O3A3; bodies 1 and 4 as dials beside their pivots. A
    frame where rod and rocker are aligned (the crank's dead point) says so."""
    times = result["time"]
    frames = [int(np.searchsorted(times, t)) for t in np.arange(0.0, duration, 1.0 / fps)]
    reach = max(l2, l3)
    fig, ax = plt.subplots(figsize=(6, 5))
    ax.set(xlim=(-l2 - 0.3, l + l3 + 0.3), ylim=(-reach - 0.3, reach + 0.3), aspect="equal", title=title)
    ax.axis("off")
    ax.plot([0.0, l], [0.0, 0.0], "k:", lw=1)
    ax.plot([0.0, l], [0.0, 0.0], "k^", ms=12)
    crank, = ax.plot([], [], "-o", lw=4, color="tab:blue", label="crank (body 2)")
    rod, = ax.plot([], [], "-o", lw=2, color="tab:gray", label="rod L")
    rocker, = ax.plot([], [], "-o", lw=4, color="tab:orange", label="rocker (body 3)")
    motor, = ax.plot([], [], "-", lw=2, color="tab:green", label="motor rotor (body 1)")
    load, = ax.plot([], [], "-", lw=2, color="tab:red", label="load (body 4)")
    label = ax.text(0.02, 0.86, "", family="monospace", transform=ax.transAxes)
    dead = ax.text(0.02, 0.80, "", color="tab:purple", transform=ax.transAxes)
    # The legend sits outside the axes so that it never covers a pin.
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, 1.0), fontsize=7, ncol=3, frameon=False)
    dial1, dial4 = np.array([-l2 - 0.18, -reach - 0.15]), np.array([l + l3 + 0.18, -reach - 0.15])
    for centre in (dial1, dial4):
        ax.add_patch(plt.Circle(centre, 0.06, fill=False, color="0.6"))
    # A short crank (case 1: 5 cm beside a 50 cm rocker) would be a few pixels: it gets an
    # inset, magnified, with the rod's first part.
    zoom = None
    if l2 < 0.2 * l3:
        half = 1.25 * l2  # half the inset's span (m)
        zoom = ax.inset_axes([0.34, 0.02, 0.32, 0.32])
        zoom.set(xlim=(-half, half), ylim=(-half, half), aspect="equal", xticks=[], yticks=[])
        zoom.set_title("the crank, magnified", fontsize=8)
        zoom.plot([0.0], [0.0], "k^", ms=8)
        zoom.add_patch(plt.Circle((0.0, 0.0), l2, fill=False, color="0.8", ls=":"))
        zoom_crank, = zoom.plot([], [], "-o", lw=3, color="tab:blue")
        zoom_rod, = zoom.plot([], [], "-", lw=2, color="tab:gray")

    def draw(i):
        phi1, phi2, phi3, phi4 = (result[f"phi{k}"][i] for k in range(1, 5))
        a2 = np.array([l2 * np.cos(phi2), l2 * np.sin(phi2)])
        a3 = np.array([l + l3 * np.cos(phi3), l3 * np.sin(phi3)])
        crank.set_data([0.0, a2[0]], [0.0, a2[1]])
        rod.set_data([a2[0], a3[0]], [a2[1], a3[1]])
        rocker.set_data([l, a3[0]], [0.0, a3[1]])
        for line, centre, phi in ((motor, dial1, phi1), (load, dial4, phi4)):
            tip = centre + 0.06 * np.array([np.cos(phi), np.sin(phi)])
            line.set_data([centre[0], tip[0]], [centre[1], tip[1]])
        label.set_text(f"t = {times[i]:4.2f} s  ω1 = {result['omega1'][i]:5.2f}  ω2 = {result['omega2'][i]:5.2f} rad/s")
        along, arm = a3 - a2, a3 - np.array([l, 0.0])
        aligned = abs(along[0] * arm[1] - along[1] * arm[0]) < 0.06 * np.linalg.norm(along) * l3
        dead.set_text("rod and rocker aligned: the crank's dead point" if aligned else "")
        if zoom is None:
            return crank, rod, rocker, motor, load, label, dead
        toward = a2 + along / np.linalg.norm(along) * 3.0 * l2
        zoom_crank.set_data([0.0, a2[0]], [0.0, a2[1]])
        zoom_rod.set_data([a2[0], toward[0]], [a2[1], toward[1]])
        return crank, rod, rocker, motor, load, label, dead, zoom_crank, zoom_rod

    FuncAnimation(fig, draw, frames=frames, blit=True).save(path, writer=PillowWriter(fps=fps))
    plt.close(fig)


# A change-point linkage (l2 + L = l + l3: crank, rod and rocker collinear at φ2 = φ3 = 0),
# moving freely from a push of the crank.
CHANGE_POINT = dict(builtin_laws=False, L=0.95, phi2_0=np.pi / 2, omega2_0=4.0)


def plot_change_point(fmu3, path, stop_time=10.0):
    """FMI 3.0 Co-Simulation with event mode: the step returns early before each change
    point, and the linkage goes on along the branch `change_point_branch` names."""
    runs = {}
    for branch, name in ((1, "straight"), (2, "turn")):
        runs[name] = fmpy.simulate_fmu(
            str(fmu3), fmi_type="CoSimulation", stop_time=stop_time, output_interval=1e-3,
            relative_tolerance=1e-10, use_event_mode=True, early_return_allowed=True,
            start_values=dict(CHANGE_POINT, change_point_branch=branch),
            output=["phi2", "phi3", "energy"], record_events=False)
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.5))
    for (name, result), style in zip(runs.items(), ("-", "--")):
        left.plot(result["time"], result["phi3"], style, label=f"φ3, branch {name}")
        wrapped = (result["phi2"] + np.pi) % (2 * np.pi) - np.pi
        right.plot(wrapped, result["phi3"], ".", markersize=1.5, label=f"branch {name}")
        drift = np.abs(result["energy"] - result["energy"][0]).max() / result["energy"][0]
        print(f"change point, branch {name}: energy drift {drift:.1e} over {stop_time:g} s")
    left.set(xlabel="time (s)", ylabel="φ3 (rad)",
             title="φ3 through the change points (the same until the first)")
    right.set(xlabel="φ2, wrapped to (−π, π] (rad)", ylabel="φ3 (rad)",
              title="The loop's configurations: two branches cross at (0, 0)")
    for ax in (left, right):
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", markerscale=6)
    fig.suptitle("A change-point linkage through FMI 3.0 with event mode (docs/model.md §7)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(fmu, out, fmu3=None):
    out.mkdir(parents=True, exist_ok=True)
    written = []
    results = {}
    for case, values in CASES.items():
        result = simulate(str(fmu), values)
        results[case] = result
        csv = out / f"{case}.csv"
        write_csv(str(csv), result)
        written.append(csv)
        for names, figure in ((("phi1", "phi2"), "phi1_phi2"), (("phi3", "phi4"), "phi3_phi4")):
            png = out / f"{case}_{figure}.png"
            plot_pair(result, names, TITLES[case], png)
            written.append(png)
        final = {name: result[name][-1] for name in ("phi1", "phi2", "phi3", "phi4", "omega1")}
        print(f"{case} at t = 10 s: " + ", ".join(f"{k} = {v:.8f}" for k, v in final.items()))
        print(f"{case}: max |constraint_residual| = {np.max(np.abs(result['constraint_residual'])):.1e} m")
    overview = out / "paper_figures.png"
    plot_overview(results, overview)
    speeds = out / "speeds_and_twists.png"
    plot_speeds_and_twists(results, speeds)
    written.append(speeds)
    gif = out / "linkage_case1.gif"
    animate_linkage(results["case1"], gif, "Case 1, first 3 s")
    # A non-Grashof linkage (s + g > p + q): no link turns fully; the crank swings back
    # through its dead points, where rod and rocker are aligned.
    swinging = simulate(str(fmu), dict(NON_GRASHOF, **PAPER_LAWS), stop_time=4.0)
    swinging_gif = out / "linkage_non_grashof.gif"
    animate_linkage(swinging, swinging_gif, "A non-Grashof linkage, paper laws, first 4 s",
                    duration=4.0, **{k: NON_GRASHOF[k] for k in ("l", "l2", "l3")})
    written += [overview, gif, swinging_gif]
    if fmu3 is not None:
        branches = out / "change_point_branches.png"
        plot_change_point(fmu3, branches)
        written.append(branches)
    print("Written:")
    for path in written:
        print(f"  {path}")


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4):
        sys.exit("usage: demo.py <CyclicMechanism.fmu> <output directory> "
                 "[<CyclicMechanism-fmi3.fmu>]")
    main(pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2]),
         pathlib.Path(sys.argv[3]) if len(sys.argv) == 4 else None)
