"""A procedural tooth row: crowns as closed triangle meshes, the gum as a capsule, and the surface
samples (with their anatomical region) on which brushing coverage is measured (issue 13).

Frame of the row (world, mm): the teeth stand along x (mesiodistal), the crown axis points +y
(occlusal), the buccal surfaces face +z, towards a brush held above them as over the paper's
plate; every crown's buccal height of contour touches the plane z = 0, so "touching" and the 3 mm
press mean what they mean on the plate.  The cemento-enamel junction (CEJ) is at y = 0: crown
above, root below (inside the gum).

Crown dimensions: Nelson, *Wheeler's Dental Anatomy, Physiology and Occlusion*, 10th ed. (2015),
the measurement table of each maxillary tooth (crown length cervico-occlusal, mesiodistal and
buccolingual diameters of the crown and at the cervix).  The shape is ours: each horizontal
section a superellipse (exponent ``SECTION_EXPONENT``: a rounded rectangle), widening from the
cervix to the height of contour and closing in a rounded occlusal table (no cusps, no fissures).
The gaps between neighbouring crowns at their widest (``gap_mm``) stand for the 0.5-1 mm
interdental spaces the issue asks for; below the contact level the embrasures open towards the
cervix as the mesiodistal width falls from crown to cervix.

The gum is a capsule along the row, through the CEJ at the cervical buccal surface and a little
behind the crowns' buccal bulge: it closes the row below the CEJ (the brush reaches it when it
works at the gum line), and between the teeth it rises as a papilla.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SECTION_EXPONENT = 2.5  # superellipse |x/a|^n + |z/b|^n = 1 of each section (2: an ellipse)

#: Nelson (2015), maxillary teeth [mm]: crown length, MD crown, MD cervix, BL crown, BL cervix
WHEELER_MAXILLARY = {
    "PM1": (8.5, 7.0, 5.0, 9.0, 8.0),
    "PM2": (8.5, 7.0, 5.0, 9.0, 8.0),
    "M1": (7.5, 10.0, 8.0, 11.0, 10.0),
    "M2": (7.0, 9.0, 7.0, 11.0, 10.0),
}

# region codes of the surface samples
BUCCAL, OCCLUSAL, INTERPROXIMAL, LINGUAL = 0, 1, 2, 3
REGIONS = ("buccal", "occlusal", "interproximal", "lingual")
REACHABLE = (BUCCAL, OCCLUSAL, INTERPROXIMAL)  # from a brush on the buccal side


@dataclass(frozen=True)
class ToothSpec:
    """One crown [mm]: its name, the Wheeler dimensions and its centre on the row (x)."""

    name: str
    crown_length: float
    md_crown: float
    md_cervix: float
    bl_crown: float
    bl_cervix: float
    x: float = 0.0
    root_length: float = 4.0  # [mm] of root modelled below the CEJ (hidden in the gum)

    @property
    def z_axis(self) -> float:
        """z of the crown's axis: its buccal height of contour at z = 0."""
        return -0.5 * self.bl_crown


def row_specs(teeth=("PM1", "PM2", "M1", "M2"), gap_mm: float = 0.7) -> list[ToothSpec]:
    """The teeth named (keys of WHEELER_MAXILLARY) side by side along +x, ``gap_mm`` apart at
    their widest, the row centred on x = 0."""
    specs: list[ToothSpec] = []
    x = 0.0
    for k, name in enumerate(teeth):
        if name not in WHEELER_MAXILLARY:
            raise ValueError(
                f"tooth {name!r} is unknown: allowed {sorted(WHEELER_MAXILLARY)} "
                "(Wheeler's maxillary premolars and molars)"
            )
        cl, mdc, mdv, blc, blv = WHEELER_MAXILLARY[name]
        if k:
            x += 0.5 * specs[-1].md_crown + gap_mm + 0.5 * mdc
        specs.append(ToothSpec(name, cl, mdc, mdv, blc, blv, x))
    shift = 0.5 * (specs[0].x + specs[-1].x)
    return [ToothSpec(**{**s.__dict__, "x": s.x - shift}) for s in specs]


def _smooth(u):
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def _profile(s: ToothSpec, y: np.ndarray):
    """Half widths (a along x, b along z) [mm] of the section at heights y (CEJ = 0)."""
    cl, rl = s.crown_length, s.root_length
    a_c, b_c = 0.5 * s.md_cervix, 0.5 * s.bl_cervix
    a_m, b_m = 0.5 * s.md_crown, 0.5 * s.bl_crown
    # crown: cervix -> height of contour (b at 1/3, a at 2/3 of the crown: buccal bulge low,
    # contact areas high), then a rounded occlusal table over the top 35 %
    a = np.where(y >= 0, a_c + (a_m - a_c) * _smooth(y / (0.65 * cl)), a_c * (1 + 0.12 * y / rl))
    b = np.where(y >= 0, b_c + (b_m - b_c) * _smooth(y / (0.35 * cl)), b_c * (1 + 0.12 * y / rl))
    top = np.clip((y - 0.65 * cl) / (0.35 * cl), 0.0, 1.0)
    bot = np.clip((-y - 0.7 * rl) / (0.3 * rl), 0.0, 1.0)
    close = np.sqrt(np.clip(1.0 - np.maximum(top, bot) ** 2, 0.0, 1.0))
    return a * close, b * close


def tooth_mesh(s: ToothSpec, n_around: int = 64, n_along: int = 48):
    """Closed, outward-oriented triangle mesh (V (nv, 3), T (nt, 3)) of one tooth, rings of
    ``n_around`` vertices at ``n_along`` heights (denser at the rounded ends) and a pole at
    each end."""
    cl, rl = s.crown_length, s.root_length
    u = np.linspace(0.0, 1.0, n_along + 2)[1:-1]
    # heights from the root end to the occlusal top, clustered at both ends (cosine spacing)
    y = -rl + (cl + rl) * 0.5 * (1.0 - np.cos(np.pi * u))
    a, b = _profile(s, y)
    th = np.linspace(0.0, 2.0 * np.pi, n_around, endpoint=False)
    e = 2.0 / SECTION_EXPONENT
    cx = np.sign(np.cos(th)) * np.abs(np.cos(th)) ** e
    cz = np.sign(np.sin(th)) * np.abs(np.sin(th)) ** e
    rings = np.stack(
        [
            s.x + a[:, None] * cx[None, :],
            np.repeat(y[:, None], n_around, 1),
            s.z_axis + b[:, None] * cz[None, :],
        ],
        axis=-1,
    ).reshape(-1, 3)
    V = np.vstack([rings, [[s.x, -rl, s.z_axis]], [[s.x, cl, s.z_axis]]])
    bottom, top = len(V) - 2, len(V) - 1
    T = []
    for i in range(n_along - 1):
        for j in range(n_around):
            p = i * n_around + j
            q = i * n_around + (j + 1) % n_around
            T.append((p, q + n_around, q))
            T.append((p, p + n_around, q + n_around))
    last = (n_along - 1) * n_around
    for j in range(n_around):
        jn = (j + 1) % n_around
        T.append((bottom, j, jn))
        T.append((top, last + jn, last + j))
    tri = np.asarray(T, np.int64)
    if signed_volume(V, tri) < 0:
        tri = tri[:, ::-1].copy()
    return V, tri


def signed_volume(V: np.ndarray, T: np.ndarray) -> float:
    """Volume enclosed by a closed mesh [mm^3]; negative if its triangles face inwards."""
    P = V[T]
    return float(np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])).sum() / 6.0)


def gum_capsule(specs, radius: float = 8.0, margin: float = 3.0):
    """(end a, end b, radius) [mm] of the gum: along x past both ends of the row by ``margin``,
    its surface through the buccal CEJ of the widest-necked tooth (0.2 mm behind it) and its crest
    0.3 mm behind the crowns' buccal plane z = 0."""
    z_cej = max(s.z_axis + 0.5 * s.bl_cervix for s in specs) - 0.2
    z_top = -0.3
    # centre (y_g, z_top - r): through (0, z_cej) -> y_g^2 + (r - (z_top - z_cej))^2 = r^2
    dz = z_top - z_cej
    y_g = -np.sqrt(max(2.0 * radius * dz - dz * dz, 0.0))
    zc = z_top - radius
    x0 = min(s.x - 0.5 * s.md_crown for s in specs) - margin
    x1 = max(s.x + 0.5 * s.md_crown for s in specs) + margin
    return (x0, y_g, zc), (x1, y_g, zc), radius


def surface_samples(V: np.ndarray, T: np.ndarray):
    """Coverage samples of one tooth: triangle centroids (n, 3) [mm], areas (n,) [mm^2] and
    region codes (n,) of the crown's triangles (centroid above the CEJ, y >= 0): buccal (normal
    mostly +z), lingual (-z), occlusal (+y) or interproximal (+-x, facing a neighbour)."""
    P = V[T]
    c = P.mean(axis=1)
    n = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    area = 0.5 * np.linalg.norm(n, axis=1)
    n = n / np.maximum(2.0 * area, 1e-300)[:, None]
    keep = c[:, 1] >= 0.0
    c, n, area = c[keep], n[keep], area[keep]
    region = np.where(n[:, 2] >= 0.0, BUCCAL, LINGUAL)
    region = np.where(np.abs(n[:, 0]) > np.maximum(np.abs(n[:, 2]), n[:, 1]), INTERPROXIMAL, region)
    region = np.where(n[:, 1] > np.maximum(np.abs(n[:, 0]), np.abs(n[:, 2])), OCCLUSAL, region)
    return c, area, region.astype(np.int64)
