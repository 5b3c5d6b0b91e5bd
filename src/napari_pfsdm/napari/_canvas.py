"""The matplotlib canvas of the plots: a full redraw spread over turns of the event loop.

A redraw of a plot (``figure.clear()`` and new artists) is followed by matplotlib's
constrained layout (~45 ms for two axes and a colour bar here, measured with the stack
sampler of ``benchmarks/plugin.py``; 156 ms of a 175 ms gap for the first figure of a new
canvas at 47,700 objects, measuring its texts) and the drawing itself (~35-65 ms, 110-135 ms
for the comparison view on a slower day). In one turn they froze the viewer for longer than
a person notices (100 ms); :class:`PlotCanvas` lays the figure out in parts (each axes'
decorations measured on their own, then the layout engine with those sizes) and draws it
in the turns after, an artist of an axes (or any other artist of the figure) at a time,
going on in the next turn once :data:`DRAW_BUDGET_S` has passed, each turn after what else
is due (:func:`._alive.next_turn`). Meanwhile a repaint shows a copy of the last full
drawing, never half of one.
"""

from __future__ import annotations

import time
import traceback
import warnings
from contextlib import contextmanager
from itertools import chain

from matplotlib.backend_bases import DrawEvent
from matplotlib.backends.backend_agg import RendererAgg
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.layout_engine import ConstrainedLayoutEngine
from matplotlib.transforms import Bbox

from ._alive import next_turn

#: A layout or a full drawing goes on in the next turn of the event loop once this much time
#: has passed in one (seconds); an axes is drawn an artist of it at a time (its axes lines
#: with their ticks and labels are one each), any other artist in one go.
DRAW_BUDGET_S = 0.03


def _parts_drawn(artist, renderer):
    """Draw ``artist`` on ``renderer`` in parts, yielding before each part (a pause may come there):
    an :class:`~matplotlib.axes.Axes` as its own ``draw`` does on an Agg picture (the same
    artists in the same order), one child at a time; any other artist, or an axes whose
    drawing is not the plain one (rasterised, filtered, hidden axes lines), in one part.

    Seen here (benchmarks/plugin.py ``--stacks``, 47,700 objects): an axes of the comparison
    view in one go was the 141 ms longest gap of Open plots, 99 ms of it its axes lines."""
    from matplotlib.axes import Axes

    plain = (isinstance(artist, Axes) and artist.get_visible() and artist.axison
             and getattr(artist, "_frameon", None) is True
             and getattr(artist, "_rasterization_zorder", None) is None
             and not artist.get_rasterized() and artist.get_agg_filter() is None
             and hasattr(artist, "_unstale_viewLim")
             and hasattr(artist, "_update_title_position"))
    if not plain:
        yield
        artist.draw(renderer)
        return
    ax = artist
    # matplotlib 3.11's Axes.draw (the compositing of images is a plain loop on Agg, which
    # draws images itself: RendererAgg.option_image_nocomposite)
    ax._unstale_viewLim()
    renderer.open_group("axes", gid=ax.get_gid())
    ax._stale = True
    locator = ax.get_axes_locator()
    ax.apply_aspect(locator(ax, renderer) if locator else None)
    children = ax.get_children()
    children.remove(ax.patch)
    ax._update_title_position(renderer)
    children = sorted((a for a in children if not a.get_animated()),
                      key=lambda a: a.get_zorder())
    for child in [ax.patch, *children]:
        yield
        child.draw(renderer)
    renderer.close_group("axes")
    ax.stale = False


#: How many times the layout measures the decorations and places the axes (matplotlib's
#: own layout: twice; tick labels change with the size of an axes).
LAYOUT_PASSES = 2


def _budgeted(parts):
    """Run ``parts`` (a generator yielding before each part of some work), yielding once
    :data:`DRAW_BUDGET_S` has passed since the last yield (never before the first part)."""
    start = time.perf_counter()
    first = True
    for _part in parts:
        if not first and time.perf_counter() - start > DRAW_BUDGET_S:
            yield
            start = time.perf_counter()
        first = False


def _place(ax, renderer):
    """Where ``ax`` is drawn, in pixels: its place in the layout made smaller to keep its
    aspect (:meth:`~matplotlib.axes.Axes.apply_aspect`, as its tight box does)."""
    locator = ax.get_axes_locator()
    ax.apply_aspect(locator(ax, renderer) if locator else None)
    return ax.get_position(original=False).transformed(ax.get_figure(root=False).transSubfigure)


def _margins(ax, renderer) -> tuple[float, float, float, float] | None:
    """How far ``ax``'s decorations reach beyond where it is drawn (:func:`_place`), in
    pixels (left, bottom, right, top), as the layout sees them; None when the layout
    leaves it out."""
    box = ax.get_tightbbox(renderer, for_layout_only=True)
    if box is None:
        return None
    place = _place(ax, renderer)
    return place.x0 - box.x0, place.y0 - box.y0, box.x1 - place.x1, box.y1 - place.y1


@contextmanager
def _decorations_as(margins: dict):
    """Within: each axes' tight box is where it is drawn with the given margins around it
    (measured before, :func:`_margins`), not measured again; how the layout engine asks
    for it."""
    def kept(ax, margin):
        def get_tightbbox(renderer=None, *args, **kwargs):
            place = _place(ax, renderer)
            return Bbox.from_extents(place.x0 - margin[0], place.y0 - margin[1],
                                     place.x1 + margin[2], place.y1 + margin[3])
        return get_tightbbox

    given = [ax for ax, margin in margins.items() if margin is not None]
    for ax in given:
        ax.get_tightbbox = kept(ax, margins[ax])  # on the instance, over its class's method
    try:
        yield
    finally:
        for ax in given:
            ax.__dict__.pop("get_tightbbox", None)


class PlotCanvas(FigureCanvasQTAgg):
    """:class:`FigureCanvasQTAgg` whose idle draw lays out first, then draws in the turns
    after, both in turns of :data:`DRAW_BUDGET_S`, showing the last full drawing until
    complete.

    The figure keeps the layout of its last full draw (its engine is set to ``"none"`` once
    laid out): drawing in place (new data in the same axes) costs no layout. A new figure
    structure (``figure.set_layout_engine("constrained")``, as after ``figure.clear()``) or a
    new canvas size is laid out again.
    """

    def __init__(self, figure) -> None:
        super().__init__(figure)
        self.step_queued = False  # an idle step waits in :func:`._alive.next_turn`'s queue
        self._stages = None  # the full drawing under way, a generator (one step per turn)
        self._wanted = False  # a drawing was asked for (draw_idle) and not done since
        self._spare = None  # a copy of the last full drawing, shown while drawing

    @property
    def drawing(self) -> bool:
        """True while a full drawing is under way (over several turns)."""
        return self._stages is not None

    def draw_idle(self) -> None:
        """Draw soon (once however often asked), in turns of its own; a drawing under way
        is of an older state of the figure: it starts again."""
        self._stages = None
        self._wanted = True
        if not self.step_queued:
            self.step_queued = True
            next_turn(self._idle_step)

    def draw(self) -> None:
        """Draw now, in one go (matplotlib's own drawing; a drawing under way or asked for
        is not needed any more)."""
        self._stages = None
        self._wanted = False
        super().draw()

    @property
    def layout_pending(self) -> bool:
        """True when the next idle step lays the figure out (and draws in the turn after)."""
        return isinstance(self.figure.get_layout_engine(), ConstrainedLayoutEngine)

    def _idle_step(self) -> None:
        try:
            self.step_queued = False
            if not self._wanted or self.width() <= 0 or self.height() <= 0:
                return
        except RuntimeError:  # the Qt widget is gone (its dock was closed)
            return
        try:
            if self._stages is None:
                self._stages = self._shown_in_turns()
            next(self._stages)
        except StopIteration:
            self._stages = None
            self._wanted = False
            return
        except Exception:  # noqa: BLE001 - as matplotlib's own idle draw: print, go on
            self._stages = None
            traceback.print_exc()
            return
        self.step_queued = True  # more to draw, in the next turn
        next_turn(self._idle_step)

    def _shown_in_turns(self):
        """The layout (when pending), then the drawing in the turns after (a generator)."""
        if self.layout_pending and self.figure.axes:
            yield from _budgeted(self._layout_parts())
            self.figure.set_layout_engine("none")
            yield  # the drawing in a turn of its own
        yield from self._draw_in_turns()

    def _layout_parts(self):
        """matplotlib's constrained layout, measured a part at a time (a generator yielding
        before each part).

        Measuring each axes' decorations (tick labels, labels, title: its tight box) is what
        the layout costs: 110-200 ms for two axes and a colour bar here, in one go. Here each
        axes' decorations are measured in parts of their own (its x axis, its y axis, then
        the whole: the first two keep their texts' sizes for the third), and the layout
        engine then runs with those sizes, kept around each axes wherever it places it
        (:func:`_decorations_as`), a few ms. Twice, as matplotlib's own layout: the second
        time with the decorations measured where the first placed the axes (tick labels
        change with the size), which is what matplotlib's second pass measures.
        """
        fig = self.figure
        renderer = self.get_renderer()
        for _pass in range(LAYOUT_PASSES):
            margins = {}
            for ax in fig.axes:
                for axis in (ax.xaxis, ax.yaxis):
                    yield
                    axis.get_tightbbox(renderer)
                yield
                margins[ax] = _margins(ax, renderer)
            yield
            with _decorations_as(margins), warnings.catch_warnings():
                # a dock squeezed for a moment (napari laying its window out again): the
                # last layout is kept, and the next size is laid out again; not a warning
                # for the user
                warnings.filterwarnings("ignore", "constrained_layout not applied")
                fig.get_layout_engine().execute(fig)

    def _draw_in_turns(self):
        """What :meth:`FigureCanvasAgg.draw` and :meth:`Figure.draw` do, yielding once
        :data:`DRAW_BUDGET_S` has passed (a generator; the figure is laid out already).

        The drawing goes into the canvas's own picture (matplotlib keeps the sizes of texts
        per picture: the layout measured them on this one; a second picture measured them all
        again, 83 ms of a 3,000-point plot's drawing); a copy of the last full drawing is
        shown meanwhile. Ends with the new picture shown and matplotlib's ``draw_event``; a
        drawing dropped half-way (the generator closed) shows the last full one again.
        """
        fig = self.figure
        target = self.get_renderer()  # the picture of this size (a new one after a resize)
        spare = self._spare
        if spare is None or (spare.width, spare.height, spare.dpi) != (
                target.width, target.height, target.dpi):
            spare = self._spare = RendererAgg(target.width, target.height, target.dpi)
        spare.restore_region(target.copy_from_bbox(fig.bbox))  # the last full drawing ...
        self.renderer = spare  # ... is what a repaint shows meanwhile
        done = False
        try:
            target.clear()
            artists = sorted((a for a in fig.get_children()
                              if a is not fig.patch and not a.get_animated()),
                             key=lambda a: a.get_zorder())
            for ax in fig.axes:  # as Figure.draw: each axes' aspect and place first
                locator = ax.get_axes_locator()
                ax.apply_aspect(locator(ax, target) if locator else None)
            target.open_group("figure", gid=fig.get_gid())
            fig.patch.draw(target)
            # and one part more: showing the picture (what ``draw_event`` draws on it, the
            # plots' highlight, 88 ms for the ten labelled bars of the nearest shapes, came
            # in the turn of the last artist)
            yield from _budgeted(chain((part for artist in artists
                                        for part in _parts_drawn(artist, target)), [None]))
            target.close_group("figure")
            fig.stale = False
            done = True
        finally:
            if not done:  # dropped: the last full drawing back where it was
                target.restore_region(spare.copy_from_bbox(fig.bbox))
            self.renderer = target
        self.callbacks.process("draw_event", DrawEvent("draw_event", self, target))
        self.update()  # Qt paints the new picture

    def print_figure(self, *args, **kwargs):
        """``figure.savefig``: the file is drawn as matplotlib draws it, and the screen's
        picture is kept.

        matplotlib leaves the canvas holding the file's picture (another size, another dpi)
        and asks Qt's next paint for a full drawing, in one go inside the paint: the whole
        figure drawn on the GUI thread, and the highlight's blit then repainted the widget
        from within its own paint ("Recursive repaint detected", "QPainter::begin: Paint
        device returned engine == 0"). The screen's picture is still right: it is kept, and
        no drawing is asked for."""
        kept = getattr(self, "renderer", None), getattr(self, "_lastKey", None)
        try:
            return super().print_figure(*args, **kwargs)
        finally:
            if kept[0] is not None:
                self.renderer, self._lastKey = kept
                self._draw_pending = False

    def resizeEvent(self, event) -> None:  # noqa: N802 - Qt's name
        """A new size: lay the figure out again before the next draw."""
        if self.figure.get_layout_engine() is not None and not self.layout_pending:
            self.figure.set_layout_engine("constrained")
        super().resizeEvent(event)
