"""The legend's characters drawn ahead, soon after the panel is docked.

napari draws each character the first time it shows it by rendering its distance field on
the GUI thread (``QtTextureFont._load_char``; about 6 ms a character on this machine), once
per viewer: all the texts of a viewer share one font cache. The legend uses some sixty
different characters, so the first Run's legend froze the viewer for about 0.4 s while
napari drew them (``benchmarks/plugin.py --stacks "run"`` on the real movie c).

Shortly after docking, and during a Run that lasts (if any are left), :class:`GlyphWarmer`
has napari draw those characters a few per turn (as many as the viewer's longest stall at
the last turn says fit in :data:`BUDGET_MS`) in the viewer's text overlay (public model:
text, colour, visibility), in a transparent colour, then puts the overlay back as it was. A
user who shows the overlay is left alone. A Run that ends stops it (and its pending start):
the legend then draws what is left, as before. It only saves time; when anything goes wrong
it stops.
"""

from __future__ import annotations

import string
import time

from qtpy.QtCore import QTimer

from ._layers import LEGENDS


def _in_order(*texts: str) -> str:
    """The characters of ``texts``, each once, in order of first appearance, no spaces."""
    return "".join(dict.fromkeys(c for c in "".join(texts) if not c.isspace()))


#: The characters of the legend, those of every legend first (its words, the colour bars'
#: numbers and units), then the rest of the alphabet for the notes.
LEGEND_CHARACTERS = _in_order(
    *(t for pair in LEGENDS.values() for t in pair), "frame · label yellow = skeleton",
    string.digits, "−.px+-e%", string.ascii_lowercase, string.ascii_uppercase,
    ".,:;()[]=+-−×·%/'")
#: At most this many characters per turn, and the shortest pause between turns (ms; as
#: long as the last turn's repaint when that was longer). Each turn also repaints the canvas
#: (the overlay changed), which costs more with large layers than a character does.
PER_TURN = 12
INTERVAL_MS = 40
#: How long the viewer may stall at one turn (ms; the repaint with its new characters, under
#: issue 23's 100 ms; the repaint of a 1024² movie varies by ±30 ms from turn to turn): each
#: turn draws as many characters as the last turn's stall says fit (at least one, at most
#: :data:`PER_TURN`), starting with :data:`FIRST_TURN`. A character costs ~6 ms on a quiet
#: machine, 20-60 ms while the worker processes start and the modules load after docking:
#: twelve a turn then made ten 200-800 ms gaps in the 3 s after docking (``/tmp`` probe on
#: the sample, eleventh session). The canvas' own repaint (~50 ms for a 1024² movie under
#: llvmpipe) does not grow with the characters: a turn that stalled less than this draws one
#: more character the next turn, at least. One character a turn made ~80 repaints, which ran
#: on into the Run and took CPU from its processes; now ~25 turns of 1-6, gaps of 52-118 ms,
#: most under 95 (``/tmp`` probe, thirteenth session).
BUDGET_MS = 70
FIRST_TURN = 2
#: The repaint is measured as the longest stall of the viewer's event loop between two turns,
#: by a clock ticking this often (ms) while the characters are drawn. (Measured as the next
#: turn's lateness, a repaint that fitted in the pause counted as free, and the turn after it
#: drew twelve characters: 96-153 ms gaps after docking a 1024² movie, thirteenth session.)
CLOCK_MS = 10
#: A start that waits for something else to finish first (``ready`` of
#: :meth:`GlyphWarmer.start_in`) asks again this often (ms), and starts anyway after
#: :data:`READY_WAIT_MS` more.
READY_POLL_MS = 100
READY_WAIT_MS = 10_000


def characters_per_turn(stall_ms: float, shown: int) -> int:
    """How many characters the next turn draws, from the last turn's: ``shown`` characters
    whose repaint (and whatever else ran before the next turn) stalled the viewer
    ``stall_ms``. As many as fit in :data:`BUDGET_MS` if all of the stall were the
    characters' (an estimate on the small side: the canvas' repaint is part of it), and one
    more than the last turn when the stall was under the budget.

    >>> characters_per_turn(20.0, 4), characters_per_turn(300.0, 12), characters_per_turn(0, 2)
    (12, 2, 12)
    >>> characters_per_turn(60.0, 2), characters_per_turn(70.0, 5), characters_per_turn(130.0, 1)
    (3, 5, 1)
    """
    shown = max(int(shown), 1)
    if stall_ms <= 0:
        return PER_TURN
    fit = int(shown * BUDGET_MS // float(stall_ms))
    if stall_ms < BUDGET_MS:
        fit = max(fit, shown + 1)
    return int(min(PER_TURN, max(1, fit)))


def text_overlay(viewer):
    """The viewer's text overlay (``viewer.canvas.overlays.text`` from napari 0.9 on, before
    that ``viewer.text_overlay``), or None."""
    try:
        return viewer.canvas.overlays.text
    except AttributeError:
        return getattr(viewer, "text_overlay", None)


class GlyphWarmer:
    """Draws :data:`LEGEND_CHARACTERS` that ``drawn`` (the viewer's set of characters drawn
    so far) lacks, :data:`PER_TURN` per turn, in ``viewer``'s text overlay."""

    def __init__(self, viewer, drawn: set, parent=None) -> None:
        self.viewer = viewer
        self.drawn = drawn
        self._todo = self._shown = self._written = ""
        self._saved: tuple | None = None
        self._timer = QTimer(parent, interval=INTERVAL_MS, singleShot=True)
        self._timer.timeout.connect(self._turn)
        self._per_turn = FIRST_TURN
        self._clock = QTimer(parent, interval=CLOCK_MS)
        self._clock.timeout.connect(self._tick)
        self._last_tick = 0.0  # perf_counter of the clock's last tick
        self._stall = 0.0  # the longest time between two ticks since the last turn (s)
        self._later = QTimer(parent, singleShot=True)  # dies with its widget
        self._later.timeout.connect(self._start_if_wanted)
        self._wanted = self._ready = None
        self._give_up_waiting = 0.0  # when a start stops waiting for ``ready`` (perf_counter)

    def start_in(self, ms: int, wanted=None, ready=None) -> None:
        """:meth:`start` in ``ms`` milliseconds, if ``wanted()`` (default: always) is then
        true; if ``ready()`` (default: always) is then false, once it is true (asked every
        :data:`READY_POLL_MS`, for at most :data:`READY_WAIT_MS` more)."""
        self._wanted, self._ready = wanted, ready
        self._give_up_waiting = time.perf_counter() + (int(ms) + READY_WAIT_MS) / 1e3
        self._later.start(int(ms))

    def _start_if_wanted(self) -> None:
        if self._wanted is not None and not self._wanted():
            return
        if (self._ready is not None and not self._ready()
                and time.perf_counter() < self._give_up_waiting):
            self._later.start(READY_POLL_MS)
            return
        self.start()

    @property
    def active(self) -> bool:
        return self._saved is not None

    def start(self) -> None:
        """Start drawing the characters not drawn yet (nothing when all are, or when the user
        shows the text overlay)."""
        self._todo = "".join(c for c in LEGEND_CHARACTERS if c not in self.drawn)
        overlay = text_overlay(self.viewer)
        if self.active or not self._todo or overlay is None or overlay.visible:
            return
        try:
            self._saved = (overlay.text, overlay.color)
            self._written = ""
            overlay.text = ""  # a hidden text of the user's is theirs to show: put back after
            overlay.color = "transparent"
            overlay.visible = True
        except Exception:  # noqa: BLE001 - an optimisation only
            self.stop()
            return
        self._per_turn, self._stall = FIRST_TURN, 0.0
        self._last_tick = time.perf_counter()
        self._clock.start()
        self._timer.start(INTERVAL_MS)

    def _tick(self) -> None:
        now = time.perf_counter()
        self._stall = max(self._stall, now - self._last_tick)
        self._last_tick = now

    def _stall_ms(self) -> float:
        """The event loop's longest stall since the last turn (ms): the longest time between
        two ticks of the clock (up to now), less the clock's period."""
        now = time.perf_counter()
        return 1e3 * max(self._stall, now - self._last_tick) - CLOCK_MS

    def _turn(self) -> None:
        overlay = text_overlay(self.viewer)
        if overlay is None or overlay.text not in ("", self._written):
            self.stop()  # the user wrote in the overlay: theirs from now on
            return
        self.drawn.update(self._shown)  # the canvas painted it since the last turn
        pause = INTERVAL_MS
        if self._shown:
            stall = self._stall_ms()
            self._per_turn = characters_per_turn(stall, len(self._shown))
            # the viewer free at least half of the time: a pause as long as the stall
            pause = int(min(max(INTERVAL_MS, round(stall)), 1000))
        self._stall = 0.0
        n = self._per_turn
        self._shown, self._todo = self._todo[:n], self._todo[n:]
        if not self._shown:
            self.stop()
            return
        try:
            overlay.text = self._written = self._shown  # drawn at the canvas' next paint
        except Exception:  # noqa: BLE001 - an optimisation only
            self.stop()
            return
        self._timer.start(pause)

    def stop(self) -> None:
        """Put the overlay back as it was."""
        self._later.stop()
        self._timer.stop()
        self._clock.stop()
        self._shown = ""
        saved, self._saved = self._saved, None
        if saved is None:
            return
        try:
            overlay = text_overlay(self.viewer)
            if overlay.text not in ("", self._written):  # the user wrote in it meanwhile:
                overlay.color = saved[1]  # theirs, in their colour
                return
            overlay.visible = False
            overlay.text, overlay.color = saved
        except Exception:  # noqa: BLE001 - e.g. the viewer closed meanwhile
            pass
