"""Fast numpy rendering of BrushEnv: uint8 frames of H x 2H pixels, and a matplotlib window.

Left half, the patch from above (+x right, +y up): cleaned cells teal on grey; each tip's
projection as a dot — grey off the plate, blue touching below the effectiveness window, green
inside it (cleaning), red above the per-tip limit; the TCP as a black cross; a coverage bar along
the bottom edge.  Right half, a side view along +y (x right, z up) centred on the TCP: the plate,
the head (black) and every bristle's chain root -> body centres -> tip (red when touching); a
total-normal-force bar along the bottom (green below the safe limit, red above; tick at the safe
limit; full width = hard limit).  Text at the top (issue 31): the time and the coverage on the
left, the total normal force against its safe limit on the right (``glyphs``: a 5 x 7 pixel
font).  No matplotlib is involved in ``rgb_array`` frames: drawing is index arithmetic on one
preallocated array (well under a millisecond for the default brush).
"""

from __future__ import annotations

import numpy as np

from .glyphs import draw_text

__all__ = ["Renderer", "RenderInput", "frame_texts"]

GREY = np.array([232, 232, 232], np.uint8)
TEAL = np.array([64, 160, 150], np.uint8)
WHITE = np.array([255, 255, 255], np.uint8)
BLACK = np.array([20, 20, 20], np.uint8)
DOT_OFF = np.array([150, 150, 150], np.uint8)
DOT_LOW = np.array([60, 90, 220], np.uint8)
DOT_OK = np.array([30, 150, 40], np.uint8)
DOT_HIGH = np.array([220, 40, 40], np.uint8)
BRISTLE = np.array([40, 60, 140], np.uint8)
PLATE = np.array([190, 200, 210], np.uint8)


class RenderInput:
    """What one frame needs (engine frame: plate z = 0, patch centred on the origin; mm, N)."""

    __slots__ = (
        "cleaned",
        "coverage",
        "tcp_p",
        "tip_pos",
        "tip_force",
        "tip_contact",
        "chains",
        "root_pos",
        "total_force",
        "time",
    )

    def __init__(self, **kw):
        for k in self.__slots__:
            setattr(self, k, kw.get(k) if k == "time" else kw[k])  # time [s]: None, no label


def frame_texts(
    time, coverage: float, total_force: float, safe_force: float, compact: bool = False
) -> tuple[str, str]:
    """The two labels of a frame: (left: time [s] and coverage, right: total normal force [N]
    and its safe limit); ``compact``: shorter, for frames too narrow for the full words."""
    if compact:
        left = f"cov {100 * coverage:.0f} %"
        if time is not None:
            left = f"t {time:.1f} s  " + left
        return left, f"F {total_force:.1f}/{safe_force:g} N"
    left = f"coverage {100 * coverage:.1f} %"
    if time is not None:
        left = f"t {time:.2f} s  " + left
    return left, f"F {total_force:.2f} N  limit {safe_force:g} N"


class FrameWindow:
    """``show`` puts frames of width W and height H in a matplotlib window (``human`` mode)."""

    def __init__(self, height: int, width: int):
        self.H, self.W = int(height), int(width)
        self._fig = None

    def show(self, frame: np.ndarray, fps: float) -> None:
        """Display ``frame`` in a matplotlib window; draws off-screen with a non-GUI backend."""
        import matplotlib
        import matplotlib.pyplot as plt

        interactive = matplotlib.get_backend().lower() not in (
            "agg",
            "pdf",
            "ps",
            "svg",
            "pgf",
            "cairo",
            "template",
        )
        if self._fig is None:
            if interactive:
                plt.ion()
            self._fig, ax = plt.subplots(figsize=(self.W / 100, self.H / 100), dpi=100)
            ax.set_axis_off()
            self._fig.subplots_adjust(0, 0, 1, 1)
            self._im = ax.imshow(frame)
        else:
            self._im.set_data(frame)
        if interactive:
            self._fig.canvas.draw_idle()
            plt.pause(1.0 / fps)
        else:
            self._fig.canvas.draw()

    def close(self) -> None:
        if self._fig is not None:
            import matplotlib.pyplot as plt

            plt.close(self._fig)
            self._fig = None


class Renderer(FrameWindow):
    """Draws frames; ``show`` puts them in a matplotlib window (``human`` mode)."""

    def __init__(
        self,
        height: int,
        patch_size: float,
        n_cells: int,
        view_size: float,
        tip_window: tuple,
        tip_limit: float,
        safe_force: float,
        hard_force: float,
    ):
        super().__init__(height, 2 * int(height))
        self.patch_size = float(patch_size)
        self.view = float(view_size)
        self.tip_window = tip_window
        self.tip_limit = tip_limit
        self.safe_force = safe_force
        self.hard_force = hard_force
        H = self.H
        centres = (np.arange(H) + 0.5) / H * n_cells
        self._map_rows = (n_cells - 1 - np.floor(centres)).astype(int)  # top row = +y
        self._map_cols = np.floor(centres).astype(int)
        self._frame = np.empty((H, self.W, 3), np.uint8)
        r = max(1, H // 128)
        dy, dx = np.mgrid[-r - 1 : r + 2, -r - 1 : r + 2]
        keep = dy * dy + dx * dx <= (r + 0.5) ** 2
        self._disc = np.stack([dy[keep], dx[keep]], axis=1)
        self._fig = None

    # ------------------------------------------------------------------ primitives
    def _put(self, img, rows, cols, color):
        ok = (rows >= 0) & (rows < img.shape[0]) & (cols >= 0) & (cols < img.shape[1])
        img[rows[ok], cols[ok]] = color

    def _dots(self, img, rc, color):
        if len(rc) == 0:
            return
        pts = rc[:, None, :] + self._disc[None, :, :]
        self._put(img, pts[..., 0].ravel(), pts[..., 1].ravel(), color)

    def _lines(self, img, a, b, color, thick=1):
        """Segments a[k] -> b[k] ((m, 2) row, col floats)."""
        if len(a) == 0:
            return
        n = int(min(4 * self.H, max(2, np.ceil(np.abs(b - a).max()) + 1)))
        t = np.linspace(0.0, 1.0, n)[None, :, None]
        pts = np.rint(a[:, None, :] + t * (b - a)[:, None, :]).astype(int).reshape(-1, 2)
        for d in range(thick):
            self._put(img, pts[:, 0] + d, pts[:, 1], color)

    # ------------------------------------------------------------------ frame
    def frame(self, s: RenderInput) -> np.ndarray:
        H = self.H
        img = self._frame
        left = img[:, :H]
        right = img[:, H:]
        # ---- left: coverage map
        cells = s.cleaned[self._map_rows[:, None], self._map_cols[None, :]]
        left[:] = GREY
        left[cells] = TEAL
        scale = H / self.patch_size

        def to_map(xy):
            col = (xy[:, 0] + 0.5 * self.patch_size) * scale
            row = (0.5 * self.patch_size - xy[:, 1]) * scale
            return np.stack([row, col], axis=1)

        rc = np.rint(to_map(s.tip_pos[:, :2])).astype(int)
        f = s.tip_force
        lo, hi = self.tip_window
        touching = s.tip_contact
        self._dots(left, rc[~touching], DOT_OFF)
        self._dots(left, rc[touching & (f < lo)], DOT_LOW)
        self._dots(left, rc[touching & (f >= lo) & (f <= min(hi, self.tip_limit))], DOT_OK)
        self._dots(left, rc[touching & (f > self.tip_limit)], DOT_HIGH)
        c = np.rint(to_map(np.asarray(s.tcp_p[None, :2]))).astype(int)[0]
        arm = max(3, H // 40)
        span = np.arange(-arm, arm + 1)
        self._put(left, c[0] + span, np.full_like(span, c[1]), BLACK)
        self._put(left, np.full_like(span, c[0]), c[1] + span, BLACK)
        bar = max(2, H // 64)
        left[H - bar :, :] = WHITE
        left[H - bar :, : int(round(np.clip(s.coverage, 0, 1) * H))] = TEAL
        # ---- right: side view (x right, z up), TCP centred horizontally
        right[:] = WHITE
        px = H / self.view
        z0 = 0.12 * self.view  # plate at 12 % above the bottom edge

        def to_side(p):
            col = (p[..., 0] - s.tcp_p[0]) * px + 0.5 * H
            row = H - (p[..., 2] + z0) * px
            return np.stack([row, col], axis=-1)

        plate_row = int(round(H - z0 * px))
        right[max(plate_row, 0) :, :] = PLATE
        chains = to_side(s.chains)  # (nb, k, 2)
        a = chains[:, :-1].reshape(-1, 2)
        b = chains[:, 1:].reshape(-1, 2)
        touch = np.repeat(s.tip_contact, chains.shape[1] - 1)
        self._lines(right, a[~touch], b[~touch], BRISTLE)
        self._lines(right, a[touch], b[touch], DOT_HIGH)
        roots = to_side(s.root_pos)
        order = np.argsort(roots[:, 1])
        self._lines(right, roots[order[:1]], roots[order[-1:]], BLACK, thick=max(2, H // 100))
        right[H - bar :, :] = WHITE
        frac = np.clip(s.total_force / self.hard_force, 0.0, 1.0)
        color = DOT_OK if s.total_force <= self.safe_force else DOT_HIGH
        right[H - bar :, : int(round(frac * H))] = color
        tick = int(round(self.safe_force / self.hard_force * (H - 1)))
        right[H - 3 * bar :, min(tick, H - 1)] = BLACK
        img[:, H - 1] = BLACK  # divider
        scale = self.text_scale
        left_text, right_text = self.texts(s)
        draw_text(left, left_text, 2 * scale, 2 * scale, BLACK, WHITE, scale)
        color = BLACK if s.total_force <= self.safe_force else DOT_HIGH
        draw_text(right, right_text, 2 * scale, 2 * scale, color, WHITE, scale)
        return img.copy()

    def texts(self, s: RenderInput) -> tuple[str, str]:
        """The frame's two labels (``frame_texts``), compact if the full ones do not fit."""
        full = frame_texts(s.time, s.coverage, s.total_force, self.safe_force)
        width = 6 * self.text_scale * max(len(t) for t in full) + 4 * self.text_scale
        if width <= self.H:
            return full
        return frame_texts(s.time, s.coverage, s.total_force, self.safe_force, compact=True)

    @property
    def text_scale(self) -> int:
        """Pixels per font pixel: 1 up to 300 px frames, then one more per 200 px."""
        return max(1, round(self.H / 200))
