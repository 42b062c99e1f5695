"""The error plot shows centimetre filter errors and metre drift on one readable (log) axis."""
import numpy as np

from agvsim.analysis.plots import error_vs_distance


def test_error_plot_uses_a_log_axis_and_keeps_the_legend_off_the_curves(tmp_path, monkeypatch):
    import matplotlib.figure

    saved = []
    original = matplotlib.figure.Figure.savefig

    def savefig(fig, *args, **kwargs):
        original(fig, *args, **kwargs)
        renderer = fig.canvas.get_renderer()  # the Agg canvas, while the figure is open
        saved.append((fig, fig.legends[0].get_window_extent(renderer), fig.axes[0].get_window_extent(renderer)))

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", savefig)
    d = np.linspace(0.0, 180.0, 500)
    drift = 0.8 * d / 180.0
    ekf = np.full_like(d, 0.004)
    ekf[0] = 0.0  # the start: nothing to draw on a log axis, and no error either
    path = error_vs_distance(tmp_path / "e.png", d, {"dead reckoning": drift, "EKF estimate": ekf},
                             "t", bound=np.full_like(d, 0.01))
    assert path.exists()
    fig, legend, axes_box = saved[0]
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    low, high = ax.get_ylim()
    assert low < 0.004 and high > 0.8  # both the filter's millimetres and the drift's metres are in view
    # the EKF's curve and its bound take a good share of the plot's height, not its bottom pixels
    frac = (np.log10(0.01) - np.log10(0.004)) / (np.log10(high) - np.log10(low))
    assert frac > 0.1
    assert not legend.overlaps(axes_box)
