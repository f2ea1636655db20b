"""Radial Tiling (svm/radial_tiling.h, radial_tiling_shared.h): the plane cut into Sides
segments around the origin, each a corner of a rounded regular polygon ("r-gon"), and where a
point lies in its segment.

Outputs, for the point's (x, y):
  Segment Coordinates  (r-gon parameter, distance along the segment's angle bisector, 0): the
                       parameter runs across the segment (negative before the bisector), the
                       distance is 1 on the r-gon's outline; with Normalize the parameter is
                       mapped to [0, 1] across the segment and the distance is not shifted,
                       without it the distance has 1 subtracted (0 on the outline)
  Segment ID           which segment, counter-clockwise from the x axis
  Segment Width        the largest parameter in the segment on the outline (its half width)
  Segment Rotation     the angle of the segment's bisector from the x axis

Sides below 2 count as 2 and Roundness is clamped to [0, 1]. A fractional number of sides
leaves a last, narrower ("irregular") segment before the x axis; Roundness replaces each corner
by a circular arc whose start moves from the corner (0) to the bisector (1). Two sides with a
roundness strictly between 0 and 1 have no finite arc (it starts at tan(pi/2)): Cycles' values
there come from its float32 rounding, and Ember's agree only in part.

Cycles' kernel branches on the point's part of its segment (straight side, rounded corner,
regular or irregular segment); here each part's formula is computed over all points and the
point's own part selected, so nothing loops over points. The names follow Cycles'
(x_A_y: the angle from x to y, l_x: the length of x) shortened: `bis` the angle from a segment
divider to the bisector, `at` the point's angle from its segment's divider, `last` the angle
from the x axis back to the irregular segment's bisector.
"""
from __future__ import annotations

import numpy as np

from .base import node, scalar, stack

TAU = 2.0 * np.pi


def _mix(a, b, t):
    return a + t * (b - a)


def _signed(p, negative):
    return np.where(negative, -p, p)


def _rounded(l_coord, at, bis, r, start, normalize):
    """A regular segment's rounded corner: (distance along the bisector, parameter) where the
    corner's arc starts at angle `start` from the divider."""
    step = 2.0 * bis
    nearest = at - (at > bis) * step  # signed angle from the nearest divider
    to_bis = bis - start
    spline = (1.0 - r) * start
    l_centre = (1.0 - r) / np.cos(bis)
    ratio = np.cos(nearest) * l_centre + np.sqrt((np.cos(nearest) * l_centre) ** 2 + r * r - l_centre ** 2)
    l_bis = l_coord / ratio
    c = start - np.abs(nearest)  # the point's angle from the arc's start
    lc = l_coord * np.cos(to_bis)
    p = l_coord * np.sin(to_bis) + np.where(c < spline, lc * c + 0.5 * (1.0 - lc) * c * c / spline,
                                            spline * (0.5 * lc - 0.5) + c)
    p = _signed(p, at < bis)
    if normalize:
        by_bis = l_bis * np.tan(to_bis) + spline * (0.5 * l_bis + 0.5) + r * start
        by_coord = l_coord * np.sin(to_bis) + spline * (0.5 * lc + 0.5) + r * start
        p = p / _mix(by_bis, by_coord, c / start)
    return l_bis, p


def _straight(l_coord, at, bis):
    """A regular segment's straight side: (distance along the bisector, unnormalised parameter)."""
    l_bis = l_coord * np.cos(bis - at)
    return l_bis, _signed(l_bis * np.tan(np.abs(bis - at)), at < bis)


def _straight_norm(l_bis, r, start, to_bis):
    """The normaliser of a straight side whose corner arcs start at `start`."""
    return l_bis * np.tan(to_bis) + (1.0 - r) * start * (0.5 * l_bis + 0.5) + r * start


def _width(r, start, to_bis):
    return np.tan(to_bis) + (1.0 - r) * start + r * start


def _integer(l_coord, at, bis, segment, sides, r, normalize):
    """(distance, parameter, width, rotation) for a whole number of sides."""
    rotation = segment * 2.0 * bis + bis
    # Roundness 0: straight sides; two sides have no width.
    l0, p0 = _straight(l_coord, at, bis)
    two = sides == 2.0
    if normalize:
        p0 = np.where(two, p0, p0 / (l0 * np.tan(bis)))
    w0 = np.where(two, 0.0, np.tan(bis))
    # Roundness 1: a circle.
    p1 = _signed(np.abs(bis - at), at < bis)
    if normalize:
        p1 = p1 / bis
    # Between: straight sides meeting in arcs.
    start = bis - np.arctan((1.0 - r) * np.tan(bis))
    to_bis = bis - start
    on_arc = (at >= 2.0 * bis - start) | (at < start)
    la, pa = _rounded(l_coord, at, bis, r, start, normalize)
    ls, ps = _straight(l_coord, at, bis)
    if normalize:
        ps = ps / _straight_norm(ls, r, start, to_bis)
    lm, pm = np.where(on_arc, la, ls), np.where(on_arc, pa, ps)
    wm = _width(r, start, to_bis)
    zero, one = r == 0.0, r == 1.0
    return (np.select([zero, one], [l0, l_coord], lm), np.select([zero, one], [p0, p1], pm),
            np.select([zero, one], [w0, bis], wm), rotation)


def _fractional(l_coord, x, y, xa, at, bis, segment, sides, r, normalize):
    """(distance, parameter, width, rotation) for a fractional number of sides: the regular
    segments and the irregular last one."""
    step = 2.0 * bis
    last = np.pi - np.floor(sides) * bis  # the irregular segment's half angle
    last_div = 2.0 * last
    ratio = np.cos(bis) / np.cos(last)  # its bisector's length over a regular one's

    # Roundness 0.
    ls0, ps0 = _straight(l_coord, at, bis)
    if normalize:
        ps0 = ps0 / (ls0 * np.tan(bis))
    l_last = l_coord * np.cos(last - at)
    li0 = ratio * l_last
    pi0 = _signed(ratio * l_last * np.tan(np.abs(last - at)), at < last)
    if normalize:
        pi0 = pi0 / (ratio * l_last * np.tan(last))
    regular0 = xa < TAU - last_div
    straight0 = (np.where(regular0, ls0, li0), np.where(regular0, ps0, pi0),
                 np.where(regular0, np.tan(bis), np.tan(last)),
                 segment * step + np.where(regular0, bis, last))

    # Roundness above 0 (calculate_out_variables_irregular_circular).
    start = bis - np.arctan((1.0 - r) * np.tan(bis))
    to_bis = bis - start
    inner_start = last - np.arctan((1.0 - r) * np.tan(last))
    inner_to_bis = last - inner_start
    radius = r * np.tan(last) / np.tan(0.5 * (bis + last))
    cx = np.cos(inner_start) / np.cos(last - inner_start) - radius * np.cos(last)
    cy = radius * np.sin(last) - np.sin(inner_start) / np.cos(last - inner_start)
    outer = np.arctan((cy + radius * np.sin(bis)) / (cx + radius * np.cos(bis)))
    outer_to_bis = bis - outer
    effective = 1.0 - np.tan(bis - outer) / np.tan(bis)
    outer_spline = (1.0 - effective) * outer
    width_regular = _width(r, start, to_bis)
    rotation_regular = segment * step + bis
    rotation_last = segment * step + last

    # Regular segments, straight sides (those next to the irregular segment normalised by its
    # outer arc).
    lst, pst = _straight(l_coord, at, bis)
    if normalize:
        near_last = (xa >= TAU - last_div - bis) | (xa < bis)
        by_outer = lst * np.tan(outer_to_bis) + outer_spline * (0.5 * lst + 0.5) + effective * outer
        pst = pst / np.where(near_last, by_outer, _straight_norm(lst, r, start, to_bis))
    # Regular segments, rounded corners.
    lrd, prd = _rounded(l_coord, at, bis, r, start, normalize)
    straight_part = (((at >= start) & (at < step - start)) | (xa >= TAU - last_div - start) | (xa < start))

    # The irregular segment, straight side.
    spline_in = (1.0 - r) * inner_start
    lis = ratio * l_last
    pis = _signed(ratio * l_last * np.tan(np.abs(last - at)), at < last)
    if normalize:
        pis = pis / (ratio * (l_last * np.tan(inner_to_bis) + spline_in * (0.5 * l_last + 0.5) + r * inner_start))
    width_last = np.tan(inner_to_bis) + ratio * (spline_in * (0.5 / ratio + 0.5) + r * inner_start)

    # The irregular segment's arcs, mirrored about its bisector: inner (its own corner) and
    # outer (the corner it shares with the first regular segment).
    msa = np.arctan2(y, x)
    mirrored = (xa >= TAU - last_div - outer) & (xa < TAU - last)
    msa = np.where(mirrored, -(msa + last_div), msa)
    proj = np.sin(msa) * cy + np.cos(msa) * cx
    l_coord_over_last = proj + np.sqrt(proj * proj + radius * radius - cx * cx - cy * cy)
    l_last_arc = l_coord / l_coord_over_last
    l_arc = ratio * l_last_arc
    c_in = inner_start - np.abs(msa)
    lc_in = l_coord * np.cos(inner_to_bis)
    p_in = ratio * l_coord * np.sin(inner_to_bis) + ratio * np.where(
        c_in < spline_in, lc_in * c_in + 0.5 * (1.0 - lc_in) * c_in * c_in / spline_in,
        spline_in * (0.5 * lc_in - 0.5) + c_in)
    p_in = _signed(p_in, at < last)
    if normalize:
        by_bis = l_last_arc * np.tan(inner_to_bis) + spline_in * (0.5 * l_last_arc + 0.5) + r * inner_start
        by_coord = l_coord * np.sin(inner_to_bis) + spline_in * (0.5 * lc_in + 0.5) + r * inner_start
        p_in = p_in / (ratio * _mix(by_bis, by_coord, c_in / inner_start))
    c_out = outer - np.abs(msa)
    lc_out = l_coord * np.cos(outer_to_bis)
    p_out = l_coord * np.sin(outer_to_bis) + np.where(
        c_out < outer_spline, lc_out * c_out + 0.5 * (1.0 - lc_out) * c_out * c_out / outer_spline,
        outer_spline * (0.5 * lc_out - 0.5) + c_out)
    p_out = _signed(p_out, at < bis)
    if normalize:
        by_bis = l_arc * np.tan(outer_to_bis) + outer_spline * (0.5 * l_arc + 0.5) + effective * outer
        by_coord = l_coord * np.sin(outer_to_bis) + outer_spline * (0.5 * lc_out + 0.5) + effective * outer
        p_out = p_out / _mix(by_bis, by_coord, c_out / outer)
    inner = msa < 0.0

    regular = (xa >= outer) & (xa < TAU - last_div - outer)
    last_straight = (xa >= TAU - last_div + inner_start) & (xa < TAU - inner_start)
    parts = [regular & straight_part, regular, last_straight, inner]
    rounded = (np.select(parts, [lst, lrd, lis, l_arc], l_arc), np.select(parts, [pst, prd, pis, p_in], p_out),
               np.select(parts, [width_regular, width_regular, width_last, width_last], width_regular),
               np.select(parts, [rotation_regular, rotation_regular, rotation_last, rotation_last], rotation_regular))
    zero = r == 0.0
    return tuple(np.where(zero, a, b) for a, b in zip(straight0, rounded))


def radial_tiling_values(x, y, sides, roundness, normalize: bool):
    """(segment coordinates (N,3), segment id, segment width, segment rotation) at points (x, y),
    as Cycles' svm_node_radial_tiling computes them."""
    x, y, sides, r = np.broadcast_arrays(*(scalar(v) for v in (x, y, np.maximum(sides, 2.0),
                                                               np.clip(roundness, 0.0, 1.0))))
    with np.errstate(all="ignore"):  # every part is computed everywhere; only the point's own is kept
        l_coord = np.sqrt(x * x + y * y)
        xa = np.arctan2(y, x) + (y < 0.0) * TAU
        # Cycles divides in float32: at two sides its bisector angle lies just past pi/2, and
        # the rounded corners' tangents take the sign that gives.
        bis = (np.float32(np.pi) / sides.astype(np.float32)).astype(np.float64)
        segment = np.floor(xa / (2.0 * bis))
        at = xa - segment * 2.0 * bis
        whole = np.modf(sides)[0] == 0.0
        integer = _integer(l_coord, at, bis, segment, sides, r, normalize)
        fraction = _fractional(l_coord, x, y, xa, at, bis, segment, sides, r, normalize)
        l_bis, p, width, rotation = (np.where(whole, a, b) for a, b in zip(integer, fraction))
        p = np.where((x == 0.0) & (y == 0.0), 0.0, p)
        if normalize:
            p = 0.5 * p + 0.5
        else:
            l_bis = l_bis - 1.0
        segment_id = np.floor(sides * (np.arctan2(y, x) / TAU + (y < 0.0)))
    return stack(p, l_bis, 0.0), segment_id, width, rotation


@node("ShaderNodeRadialTiling", "Vector")
def radial_tiling(node, inputs, state):
    v = np.asarray(inputs["Vector"], np.float64)
    coords, segment_id, width, rotation = radial_tiling_values(v[..., 0], v[..., 1], inputs["Sides"],
                                                              inputs["Roundness"], bool(node.prop("normalize", False)))
    return {"Segment Coordinates": coords, "Segment ID": segment_id, "Segment Width": width,
            "Segment Rotation": rotation}


NODES = (radial_tiling,)
