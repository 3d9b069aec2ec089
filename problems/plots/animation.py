"""The animation of a maneuver (``maneuver.gif``): every method's body frame with its thrust
arrow, the orbits, the attitude alone and a timeline of the controls, on its own Agg canvas."""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from ...transcription.ocp import TargetOrbit
from ...transcription.geometry.so3 import rotation_angle
from ...transcription.results.solution import Solution
from ...transcription.solve import Comparison
from ..io import atomic_write_bytes
from ..units import units
from .orbits import _orbit_ellipse
from .runs import _runs
from .style import COMP, FAIL, THRUST
from .targets import _target_orbit, _target_R, removed
from .views3d import _body_points, _cones, _cube


def animate(results_dir: Path, frames: int = 100, fps: int = 20, out: Path | None = None) -> Path:
    """Write ``maneuver.gif``: every method of the run (named in the legend), the body frame of
    each at orbit scale with its thrust arrow, the initial and desired orbits, and beside it the
    attitude alone (body triads against the target frame) and a timeline of |u_f| and |u_m|.

    Rendered on its own Agg canvas (the backend is not touched): the static parts are drawn once
    and every frame redraws only the moving artists (manual blitting), and the GIF is written by
    Pillow with one palette, so that an 800-frame N is as fast as a 50-frame one."""
    from ..store import read_run

    rd = read_run(results_dir)
    path = Path(out) if out is not None else Path(results_dir) / "maneuver.gif"
    return write_animation(rd.result, path, frames=frames, fps=fps)


def write_animation(result: Solution | Comparison, path: Path, frames: int = 100, fps: int = 20) -> Path:
    """The animation of :func:`animate` for a Solution or a Comparison in memory."""
    if frames < 2 or fps < 1:
        raise ValueError("frames must be >= 2 and fps >= 1")
    return Animation(result).save(path, frames, fps)


class Animation:
    """The animated figure of a Solution or a Comparison: ``fig`` (its own Agg canvas), ``frame(t)``
    renders the state at time t as an RGB image, ``save(path, frames, fps)`` writes the GIF."""

    def __init__(self, result: Solution | Comparison):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        runs = _runs(result)
        problem = runs[0].sol.problem
        first = runs[0].sol
        self.runs, self.model, self.units = runs, problem.model, units(problem)
        self.t0, self.t1 = float(first.trajectory.t[0]), float(first.trajectory.t[-1])
        fig = Figure(figsize=(9.6, 5.4), dpi=100)
        canvas = FigureCanvasAgg(fig)
        gs = fig.add_gridspec(2, 2, width_ratios=(1.45, 1), height_ratios=(1.5, 1), left=0.02, right=0.98, bottom=0.15,
                              top=0.9, wspace=0.12, hspace=0.3)
        ax = fig.add_subplot(gs[:, 0], projection="3d")
        axa = fig.add_subplot(gs[0, 1], projection="3d")
        axt = fig.add_subplot(gs[1, 1])
        for a in (ax, axa):
            a.computed_zorder = False
        self.lim, still, size = self._scene(ax, problem)
        Rd = _target_R(problem)
        self._attitude_view(axa, problem, Rd)
        controls = self._timeline(axt, problem, Rd)
        self.thrust = controls and "force" not in removed(problem)
        self._legend_and_title(fig, ax, problem)
        self._moving_artists(ax, axa, axt, 0.6 * self.lim if still else 0.16 * self.lim, size)
        for a in self.moving:
            a.set_animated(True)
        canvas.draw()
        self.fig, self.canvas, self.background = fig, canvas, canvas.copy_from_bbox(fig.bbox)

    def _scene(self, ax, problem) -> tuple[float, bool, float]:
        """The static 3-D view: central body, initial and desired orbits, each method's path, axes
        limits.  Returns the half-width of the view, whether the body stays put (a slew without a
        central body: then it is drawn at its own scale) and the body's size."""
        runs, model, first = self.runs, problem.model, self.runs[0].sol
        _, size = _body_points(problem)
        allx = np.vstack([r.sol.trajectory.x for r in runs] + ([np.zeros((1, 3))] if model.mu else []))
        allx = allx[np.all(np.isfinite(allx), axis=1)]
        extent = float(np.ptp(allx, axis=0).max()) if len(allx) else 0.0
        still = not model.mu and extent < size  # a slew without a central body: the body at its own scale
        if model.mu:
            ax.scatter([0], [0], [0], s=120, color="#3b6ea8")
            orb = _orbit_ellipse(first.trajectory.x[0], first.trajectory.v[0], model.mu)
            if orb is not None:
                ax.plot(*orb.T, color="0.55", lw=1, ls=":", label="initial orbit")
                allx = np.vstack([allx, orb])
        target = _target_orbit(problem)
        if target is not None:
            ax.plot(*target.T, color="k", lw=1, ls="--", label="desired orbit")
            allx = np.vstack([allx, target])
        center = 0.5 * (allx.max(0) + allx.min(0)) if not model.mu else np.zeros(3)
        lim = max(np.abs(allx - center).max() * 1.05, 1e-9)
        if not model.mu:
            lim = max(lim, 1.6 * size)
        for run in runs:
            ax.plot(*run.sol.trajectory.x.T, color=run.color, ls=run.ls, lw=1.2, alpha=0.6, label=run.name)
        _cube(ax, lim, center)
        ax.set_xlabel("x₁")
        ax.set_ylabel("x₂")
        ax.set_zlabel("x₃")
        return lim, still, size

    @staticmethod
    def _attitude_view(axa, problem, Rd) -> None:
        """The attitude alone: a faint unit sphere, the target frame (or orbit normal) dashed, the cones."""
        u, v = np.mgrid[0:2 * np.pi:17j, 0:np.pi:9j]
        axa.plot_wireframe(np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v), color="0.88", lw=0.4)
        if Rd is not None:
            for i in range(3):
                axa.plot(*np.vstack([np.zeros(3), 1.1 * Rd[:, i]]).T, color="k", ls="--", lw=1.2)
                axa.text(*(1.2 * Rd[:, i]), f"e{i + 1}ᵈ", fontsize=8)
        elif isinstance(problem.terminal, TargetOrbit):
            n = problem.terminal.normal
            axa.plot(*np.vstack([-1.1 * n, 1.1 * n]).T, color="k", ls="--", lw=1.2)
        _cones(axa, problem)
        _cube(axa, 1.1)
        for a in (axa.xaxis, axa.yaxis, axa.zaxis):
            a.set_ticklabels([])
        has_target = Rd is not None or isinstance(problem.terminal, TargetOrbit)
        axa.set_title("attitude" + (" (target dashed)" if has_target else ""), fontsize=9)

    def _timeline(self, axt, problem, Rd) -> bool:
        """The timeline of the control magnitudes, each over its maximum (or, without controls, the
        attitude error over its maximum).  Returns whether controls were drawn."""
        scales = []
        gone = removed(problem)
        shown = [(k, lw, a) for k, w, lw, a in (("u_f", "force", 1.3, 1.0), ("u_m", "moment", 0.9, 0.55)) if w not in gone]
        if len(shown) == 1:  # one control: drawn as strongly as the force would be
            shown = [(shown[0][0], 1.3, 1.0)]
        for run in self.runs:
            s = run.sol
            if s.controls is not None and shown:
                sc = []
                for key, lw, alpha in shown:
                    nu = np.linalg.norm(getattr(s, key), axis=1)
                    sc.append(max(nu.max(), 1e-300))
                    run.plot_control(axt, nu / sc[-1], lw=lw, alpha=alpha)
                scales.append(sc)
            else:
                E = np.einsum("ji,kjl->kil", Rd if Rd is not None else s.trajectory.R[0], s.trajectory.R)
                ang = np.degrees(rotation_angle(E))
                axt.plot(run.t, ang / max(ang.max(), 1e-300), color=run.color, ls=run.ls, lw=1.3)
        if scales:
            axt.set_ylabel("|u| / max", fontsize=8)
            axt.legend([Line2D([], [], color="0.3", lw=lw, alpha=a) for _, lw, a in shown],
                       [f"|{k}| (max {m:.3g})" for (k, _, _), m in zip(shown, scales[0])], fontsize=7, loc="upper right")
        else:
            axt.set_ylabel(("angle to target" if Rd is not None else "rotation from start") + " / max", fontsize=8)
        axt.set_xlim(self.t0, self.t1)
        axt.set_ylim(-0.05, 1.15)
        axt.xaxis.set_major_locator(MaxNLocator(nbins=5))
        axt.tick_params(labelsize=7)
        axt.set_xlabel(self.units.time_label, fontsize=8)
        axt.grid(alpha=0.3)
        return bool(scales)

    def _legend_and_title(self, fig, ax, problem) -> None:
        """The legend below, the title naming every method (and NOT CONVERGED), a red corner banner
        naming each failed method and its result code."""
        runs = self.runs
        handles, labels = ax.get_legend_handles_labels()
        handles += [Line2D([], [], color=c, lw=2) for c in COMP]
        labels += ["body e1", "body e2", "body e3"]
        if self.thrust:
            handles.append(Line2D([], [], color=THRUST, lw=2))
            labels.append("thrust u_f")
        fig.legend(handles, labels, loc="lower left", ncols=5, fontsize=8, frameon=False)
        failed = [r for r in runs if r.failed]
        names = ", ".join(f"{r.name} ({'solid' if r.ls == '-' else 'dashed'})" for r in runs)
        fig.suptitle(f"{problem.name}: {names}" + ("  —  NOT CONVERGED" if failed else ""),
                     x=0.01, ha="left", fontsize=11, color=FAIL if failed else "black")
        if failed:
            fig.text(0.99, 0.995, "\n".join(f"{r.label}: {r.sol.result.value}" for r in failed), ha="right", va="top",
                     fontsize=9, color="white", fontweight="bold",
                     bbox=dict(boxstyle="round,pad=0.3", facecolor=FAIL, edgecolor="none"))

    def _moving_artists(self, ax, axa, axt, L: float, size: float) -> None:
        """The artists :meth:`frame` moves: per method the body triad (axes of length L), the rod,
        the thrust arrow, the position and the attitude triad; the time cursor and the clock."""
        runs = self.runs
        self.L, self.scale = L, L / size
        self.fmax = max([np.linalg.norm(r.sol.u_f, axis=1).max() for r in runs if r.sol.controls is not None] + [1e-300])
        self.moving = moving = []

        def line(a, **kw):
            (ln,) = a.plot([], [], [], **kw) if a is not axt else a.plot([], [], **kw)
            moving.append(ln)
            return ln

        self.art = []
        for run in runs:
            self.art.append({"triad": [line(ax, color=COMP[i], lw=2.2, ls=run.ls, zorder=6) for i in range(3)],
                             "rod": line(ax, color="0.3", lw=3, alpha=0.6, zorder=5) if len(self.model.markers) else None,
                             "thrust": line(ax, color=THRUST, lw=2.2, ls=run.ls, zorder=7),
                             "head": line(ax, color=THRUST, marker="o", ms=4, ls="", zorder=7),
                             "dot": line(ax, color=run.color, marker="o", ms=5, ls="", zorder=8),
                             "att": [line(axa, color=COMP[i], lw=2.2, ls=run.ls) for i in range(3)]})
        self.cursor = axt.axvline(self.t0, color="k", lw=1)
        moving.append(self.cursor)
        self.clock = axt.text(0.015, 0.96, "", transform=axt.transAxes, ha="left", va="top", fontsize=9,
                              family="monospace", bbox=dict(facecolor="white", edgecolor="none", alpha=0.85, pad=1.5))
        moving.append(self.clock)

    def frame(self, time_: float) -> np.ndarray:
        """The image (height, width, 3) of the state at time ``time_``."""
        canvas, L, scale, lim, fmax, model = self.canvas, self.L, self.scale, self.lim, self.fmax, self.model
        canvas.restore_region(self.background)
        for run, d in zip(self.runs, self.art):
            s = run.sol
            k = int(np.clip(np.searchsorted(s.trajectory.t, time_), 0, s.N))
            x, R = s.trajectory.x[k], s.trajectory.R[k]
            if not (np.all(np.isfinite(x)) and np.all(np.isfinite(R))):
                continue
            for i in range(3):
                tip = x + L * R[:, i]
                d["triad"][i].set_data_3d([x[0], tip[0]], [x[1], tip[1]], [x[2], tip[2]])
                d["att"][i].set_data_3d([0, R[0, i]], [0, R[1, i]], [0, R[2, i]])
            if d["rod"] is not None:
                ends = x + scale * model.markers @ R.T
                d["rod"].set_data_3d(*ends.T)
            d["dot"].set_data_3d([x[0]], [x[1]], [x[2]])
            if s.controls is not None and self.thrust:
                j = int(np.clip(np.searchsorted(s.control_times, time_), 0, len(s.control_times) - 1))
                tip = x + 0.45 * lim * s.f_inertial[j] / fmax
                d["thrust"].set_data_3d([x[0], tip[0]], [x[1], tip[1]], [x[2], tip[2]])
                d["head"].set_data_3d([tip[0]], [tip[1]], [tip[2]])
        self.cursor.set_xdata([time_, time_])
        un = self.units
        self.clock.set_text("t = " + (un.duration(time_, "{:.3f}") if un.normalized or un.system else f"{time_:.3f}"))
        for a in self.moving:
            self.fig.draw_artist(a)
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()

    def save(self, path: Path, frames: int = 100, fps: int = 20) -> Path:
        """Write the GIF (atomically): ``frames`` images evenly spaced in time, ``fps`` a second,
        one palette for all (from the first, middle and last frames)."""
        from PIL import Image

        images = [Image.fromarray(self.frame(t)) for t in np.linspace(self.t0, self.t1, frames)]
        sample = [images[0], images[len(images) // 2], images[-1]]
        strip = Image.new("RGB", (sample[0].width * 3, sample[0].height))
        for i, im in enumerate(sample):
            strip.paste(im, (i * im.width, 0))
        palette = strip.quantize(colors=255, method=Image.Quantize.MEDIANCUT)
        frames_p = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in images]
        bio = io.BytesIO()
        frames_p[0].save(bio, format="GIF", save_all=True, append_images=frames_p[1:],
                         duration=int(round(1000 / fps)), loop=0, optimize=False)
        atomic_write_bytes(Path(path), bio.getvalue())
        return Path(path)
