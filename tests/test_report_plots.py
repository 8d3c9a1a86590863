"""The study's figures tell every method apart."""

from __future__ import annotations

import matplotlib.colors as mcolors
import pytest

from lerobot_pnp.evaluation.stats import Rate
from lerobot_pnp.report import plots


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
