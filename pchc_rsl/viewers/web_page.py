"""What the browser pages share, the web viewer's (pchc-play --viewer web) and the deploy console's (pchc-deploy
--web): viser, a free port, lambda's sliders. Neither torch nor MuJoCo is imported here, so pchc-deploy checks its
arguments without them."""

from __future__ import annotations

import socket

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8080


class WebViewerUnavailable(RuntimeError):
    """viser (or mjviser) is missing, or the port cannot be used; the message says what to do."""


def require_viser():
    try:
        import viser
        from mjviser import ViserMujocoScene
    except ImportError as error:
        raise WebViewerUnavailable(f"the web viewer needs viser and mjviser ({error}); install the extra: "
                                   "pip install -e \".[web]\"") from None
    return viser, ViserMujocoScene


def check_port(host: str, port: int) -> None:
    """Fail in one line if ``port`` is taken (viser would silently move to the next one), suggesting a free one."""
    with socket.socket() as probe:
        try:
            probe.bind((host, port))
            return
        except OSError:
            pass
    with socket.socket() as spare:
        spare.bind((host, 0))
        free = spare.getsockname()[1]
    raise WebViewerUnavailable(f"port {port} on {host} is in use (another viewer?); pass --port {free}, which is "
                               "free now")


def preference_from_sliders(values) -> list[float]:
    """Slider positions -> lambda on the simplex. One slider (two objectives) is lambda_2: t -> (1 - t, t). One
    slider per objective: their values renormalised to sum to 1 (all at 0: the middle of the simplex)."""
    values = [min(1.0, max(0.0, float(v))) for v in values]
    if len(values) == 1:
        return [1.0 - values[0], values[0]]
    total = sum(values)
    return [v / total for v in values] if total > 0 else [1.0 / len(values)] * len(values)


def add_preference_controls(gui, names: list[str], initial, on_change):
    """lambda's slider (one for two objectives, one per objective otherwise, renormalised) and a line that shows it;
    ``on_change(preference)`` runs on viser's thread. Returns (the sliders, the markdown handle of that line)."""
    if len(names) == 2:
        sliders = [gui.add_slider(f"{names[0]} <-> {names[1]}", 0.0, 1.0, 0.05, float(initial[1]),
                                  hint=f"lambda = (1 - t, t): left favours {names[0]}, right {names[1]}")]
    else:
        sliders = [gui.add_slider(name, 0.0, 1.0, 0.05, float(value)) for name, value in zip(names, initial)]
    for s in sliders:
        s.on_update(lambda _: on_change(preference_from_sliders([x.value for x in sliders])))
    return sliders, gui.add_markdown(preference_markdown(names, initial))


def preference_markdown(names: list[str], preference) -> str:
    return "lambda = (" + ", ".join(f"{n} **{float(v):.2f}**" for n, v in zip(names, preference)) + ")"
