"""The study's figures tell every method apart."""

from __future__ import annotations

import matplotlib.colors as mcolors
import pytest

from lerobot_pnp.evaluation import plots
from lerobot_pnp.evaluation.stats import Rate


@pytest.mark.parametrize("n", [3, 10, 11, 20])
def test_every_method_gets_its_own_colour(n):
    colors = [mcolors.to_hex(c) for c in plots.series_colors(n)]
    assert len(set(colors)) == n
    with pytest.raises(ValueError, match="at most 20 series"):
        plots.series_colors(21)


def test_rate_bars_with_eleven_methods_draw_eleven_colours(tmp_path, monkeypatch):
    """The full study compares 11 methods; matplotlib's default cycle gave the eleventh the colour of the first."""
    drawn = []
    real_bar = plots.plt.Axes.bar

    def bar(self, *args, **kwargs):
        drawn.append(mcolors.to_hex(kwargs["color"]))
        return real_bar(self, *args, **kwargs)

    monkeypatch.setattr(plots.plt.Axes, "bar", bar)
    rates = {f"method {i}": {"nominal": Rate(i, 20), "drop": Rate(20 - i, 20)} for i in range(11)}
    out = plots.rate_bars(rates, tmp_path / "bars.png", "test", "title")
    assert out.is_file() and len(drawn) == 11 and len(set(drawn)) == 11


def test_rate_bars_draw_each_training_seed_on_its_bar(tmp_path, monkeypatch):
    """A pooled bar carries one dot per training seed at that seed's rate; a method of one seed gets none."""
    dots = []
    real_plot = plots.plt.Axes.plot

    def plot(self, xs, ys, *args, **kwargs):
        dots.extend(zip(xs, ys))
        return real_plot(self, xs, ys, *args, **kwargs)

    monkeypatch.setattr(plots.plt.Axes, "plot", plot)
    rates = {"pooled": {"nominal": Rate(30, 40)}, "single": {"nominal": Rate(10, 20)}}
    seeds = {"pooled": {"nominal": (Rate(18, 20), Rate(12, 20))}}
    out = plots.rate_bars(rates, tmp_path / "bars.png", "test", "title", per_seed=seeds)
    assert out.is_file() and sorted(y for _, y in dots) == [60.0, 90.0]
    assert len({x for x, _ in dots}) == 1 and dots[0][0] < 0  # on the first (left) bar of the group


# ------------------------------------------------------------------------------ the held-out protocol's figures
class _Method:
    def __init__(self, name: str, learned: bool):
        self.name, self.label, self.learned = name, f"{name} label", learned


class _Layout:
    def __init__(self, root):
        self.root = root

    def figure(self, name):
        return self.root / name


class _Record:
    def __init__(self, success: bool):
        self.success = success


def _runs(rates: dict[str, float], n: int = 20) -> dict[str, list]:
    return {s: [_Record(i < round(r * n)) for i in range(n)] for s, r in rates.items()}


_SUITES = ["nominal", "train_drop", "heldout_far_drop", "heldout_latency_2", "train_latency"]
_RESULTS = {
    "expert": {"-": _runs(dict.fromkeys(_SUITES, 1.0))},
    "lookup_table": {"-": _runs(dict.fromkeys(_SUITES, 0.0))},  # fails everything: not the one to explain
    "recovering": {
        "1000": _runs(
            {
                "nominal": 1.0,
                "train_drop": 0.95,
                "heldout_far_drop": 0.9,
                "heldout_latency_2": 0.6,
                "train_latency": 1.0,
            }
        ),
        "n50": _runs({"nominal": 0.1, "heldout_far_drop": 0.0}),  # a data-efficiency run: not a main tag
    },
}
_METHODS = [_Method("expert", False), _Method("lookup_table", False), _Method("recovering", True)]


def test_failures_are_drawn_where_the_best_learned_method_fails_most():
    from lerobot_pnp.report.figures import failure_suites

    assert failure_suites(_METHODS, _RESULTS, _SUITES) == ["heldout_latency_2"]
    # the paper task's suites when they were evaluated; the first suite when nothing learned fails anywhere
    assert failure_suites(_METHODS, _RESULTS, ["nominal", "grasp_miss", "nudge_0.03"]) == ["nudge_0.03", "grasp_miss"]
    clean = {**_RESULTS, "recovering": {"1000": _runs(dict.fromkeys(_SUITES, 1.0))}}
    assert failure_suites(_METHODS, clean, _SUITES) == ["nominal"]
    assert failure_suites(_METHODS[:2], _RESULTS, _SUITES) == ["nominal"]


def test_held_out_figure_puts_each_axis_trained_suites_before_its_held_out_ones(tmp_path, monkeypatch):
    from lerobot_pnp.report import figures

    drawn = figures._held_out(_Layout(tmp_path), _METHODS, _RESULTS, _SUITES, "test")
    assert [d[1] for d in drawn] == ["held_out.png"]
    assert (tmp_path / "held_out.png").stat().st_size > 10_000
    calls = []
    monkeypatch.setattr(figures.plots, "axis_panels", lambda panels, rates, *a, **k: calls.append((panels, rates)))
    figures._held_out(_Layout(tmp_path), _METHODS, _RESULTS, _SUITES, "test")
    ((panels, rates),) = calls
    # the axes with a held-out suite evaluated, in the protocol's order, each with only the suites evaluated
    assert panels == [("magnitude", ["train_drop"], ["heldout_far_drop"]),
                      ("latency", ["train_latency"], ["heldout_latency_2"])]  # fmt: skip
    assert rates["recovering label"]["heldout_latency_2"] == Rate(12, 20)  # the main seeds only, not n50
    assert rates["lookup_table label"]["train_drop"] == Rate(0, 20)
    # a study without a held-out suite (the paper task) draws no such figure
    assert figures._held_out(_Layout(tmp_path), _METHODS, _RESULTS, ["nominal", "train_drop"], "test") == []


def test_a_long_command_footer_is_broken_into_lines_that_fit_the_figure():
    """A compare command's run paths hold no space: its footer is still broken into lines inside the figure."""
    import matplotlib.pyplot as plt

    from lerobot_pnp.evaluation.plots import FOOTER_PT, footer_lines

    command = "lerobot-pnp compare camera=" + ",".join(f"docs/results/protocol/camera_seed{s}" for s in range(6))
    fig = plt.figure(figsize=(6.4, 4.8), dpi=110)
    lines = footer_lines(fig, command)
    assert len(lines) > 1 and "".join(lines).replace(" ", "") == command.replace(" ", "")  # nothing lost
    texts = [fig.text(0.01, 0.1 * i, line, fontsize=FOOTER_PT) for i, line in enumerate(lines)]
    fig.canvas.draw()
    width = fig.bbox.width
    assert all(t.get_window_extent().x1 <= width for t in texts)
    plt.close(fig)
