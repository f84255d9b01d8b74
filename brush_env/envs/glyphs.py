"""A 5 x 7 pixel font for the text on rendered frames (time, force, coverage): numpy only, so an
``rgb_array`` frame still needs no matplotlib and stays well under a millisecond.

Only the characters the frames use are drawn; :func:`text_mask` refuses any other, so a new
label cannot silently lose a letter.
"""

from __future__ import annotations

import numpy as np

__all__ = ["GLYPHS", "text_mask", "draw_text"]

_ROWS = {
    "0": (".###.", "#...#", "#..##", "#.#.#", "##..#", "#...#", ".###."),
    "1": ("..#..", ".##..", "..#..", "..#..", "..#..", "..#..", ".###."),
    "2": (".###.", "#...#", "....#", "...#.", "..#..", ".#...", "#####"),
    "3": ("#####", "...#.", "..#..", "...#.", "....#", "#...#", ".###."),
    "4": ("...#.", "..##.", ".#.#.", "#..#.", "#####", "...#.", "...#."),
    "5": ("#####", "#....", "####.", "....#", "....#", "#...#", ".###."),
    "6": ("..##.", ".#...", "#....", "####.", "#...#", "#...#", ".###."),
    "7": ("#####", "....#", "...#.", "..#..", ".#...", ".#...", ".#..."),
    "8": (".###.", "#...#", "#...#", ".###.", "#...#", "#...#", ".###."),
    "9": (".###.", "#...#", "#...#", ".####", "....#", "...#.", ".##.."),
    ".": (".....", ".....", ".....", ".....", ".....", ".##..", ".##.."),
    "-": (".....", ".....", ".....", "#####", ".....", ".....", "....."),
    "/": (".....", "....#", "...#.", "..#..", ".#...", "#....", "....."),
    "%": ("##...", "##..#", "...#.", "..#..", ".#...", "#..##", "...##"),
    ":": (".....", ".##..", ".##..", ".....", ".##..", ".##..", "....."),
    "=": (".....", ".....", "#####", ".....", "#####", ".....", "....."),
    " ": (".....",) * 7,
    "a": (".....", ".....", ".###.", "....#", ".####", "#...#", ".####"),
    "c": (".....", ".....", ".###.", "#....", "#....", "#...#", ".###."),
    "e": (".....", ".....", ".###.", "#...#", "#####", "#....", ".###."),
    "g": (".....", ".####", "#...#", "#...#", ".####", "....#", ".###."),
    "i": ("..#..", ".....", ".##..", "..#..", "..#..", "..#..", ".###."),
    "l": (".##..", "..#..", "..#..", "..#..", "..#..", "..#..", ".###."),
    "m": (".....", ".....", "##.#.", "#.#.#", "#.#.#", "#...#", "#...#"),
    "n": (".....", ".....", "#.##.", "##..#", "#...#", "#...#", "#...#"),
    "o": (".....", ".....", ".###.", "#...#", "#...#", "#...#", ".###."),
    "r": (".....", ".....", "#.##.", "##..#", "#....", "#....", "#...."),
    "s": (".....", ".....", ".####", "#....", ".###.", "....#", "####."),
    "t": (".#...", ".#...", "###..", ".#...", ".#...", ".#..#", "..##."),
    "v": (".....", ".....", "#...#", "#...#", "#...#", ".#.#.", "..#.."),
    "F": ("#####", "#....", "#....", "####.", "#....", "#....", "#...."),
    "N": ("#...#", "#...#", "##..#", "#.#.#", "#..##", "#...#", "#...#"),
}

#: character -> (7, 5) bool mask
GLYPHS = {c: np.array([[x == "#" for x in row] for row in rows]) for c, rows in _ROWS.items()}


def text_mask(text: str, scale: int = 1) -> np.ndarray:
    """(7 scale, 6 scale len(text)) bool mask of ``text`` (one blank column after each glyph);
    ValueError naming a character the font lacks."""
    missing = sorted(set(text) - set(GLYPHS))
    if missing:
        raise ValueError(f"text {text!r}: no glyph for {missing} (brush_env/envs/glyphs.py)")
    gap = np.zeros((7, 1), bool)
    cols = [np.hstack([GLYPHS[c], gap]) for c in text] or [np.zeros((7, 0), bool)]
    mask = np.hstack(cols)
    return np.kron(mask, np.ones((scale, scale), bool)).astype(bool)


def draw_text(img: np.ndarray, text: str, row: int, col: int, color, background, scale=1):
    """Write ``text`` into ``img`` (H, W, 3) with its top-left corner at (row, col) on a box of
    ``background`` one pixel wider all round (legible on any part of the frame); clipped to the
    image.  Returns the (row0, row1, col0, col1) box drawn."""
    mask = text_mask(text, scale)
    r0, c0 = max(row - 1, 0), max(col - 1, 0)
    r1 = min(row + mask.shape[0] + 1, img.shape[0])
    c1 = min(col + mask.shape[1] + 1, img.shape[1])
    img[r0:r1, c0:c1] = background
    h, w = min(mask.shape[0], img.shape[0] - row), min(mask.shape[1], img.shape[1] - col)
    if h > 0 and w > 0:
        region = img[row : row + h, col : col + w]
        region[mask[:h, :w]] = color
    return r0, r1, c0, c1
