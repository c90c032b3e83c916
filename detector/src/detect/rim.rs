//! Candidate quads from a disc rim alone, for tags whose data square makes
//! no quad of its own.
//!
//! On a small or blurred tag the data square's one-cell white margin is
//! 1-3 px wide and the threshold joins the cells to the black frame, so no
//! border of the square closes, while the disc around it (0.82 S in radius,
//! black on white) still gives a clean rim. The rim and its centre fix the
//! tag's projection up to its rotation about the centre: with the tag small
//! against its distance, the projection is affine, and the affine maps
//! taking the disc to the rim are `Rot(phi) diag(a, b) Rot(psi)` / R for the
//! rim's axes `a`, `b` and major-axis angle `phi`, any `psi` (orientation
//! preserving: a tag is seen from its printed side). The rotation `psi`,
//! modulo 90 degrees (the decoder tries the four rotations), comes from the
//! gradients inside the frame, brought back to the tag's plane: the frame's
//! sides and the cells' edges all run along the square's two axes, so the
//! gradient directions' fourth harmonic has phase `4 psi` (the
//! structure-tensor idea, with angles quadrupled for a four-fold pattern).
//! The quad's sides are then measured by refinement along the predicted
//! ones, and a reading stands only on the verify stage's model fit, which
//! places the corners once the id is known and says which the image
//! supports (`decoding::rim_reading_stands`).

use super::ellipses::Ellipse;
use super::print_align;
use super::quads::{Candidate, Edges};
use crate::homography::Homography;
use crate::math::{mean_side, norm, sample_bilinear, to_full};
use crate::view::GrayView;

/// Radius of the disc rim in units of the data square's side S: the black
/// disc ends at `r + b sqrt(2) - b/2` with `r = S sqrt(2)/2`, `b = S/8`
/// (the format's geometry, items 2 and 9).
pub(crate) const RIM_RADIUS: f64 = 0.821_4;

/// The rim's border points are the centres of the dark region's outermost
/// pixels, half a pixel inside the edge they follow (working px): on the
/// wild set, quads from the fitted axes alone were 4% too small at the
/// median, half a working pixel on a typical rim.
const RIM_BORDER_OFFSET: f64 = 0.5;

/// Gradients are taken inside this radius (units of S) of the tag's plane:
/// the data square and its black frame (to 0.625 S at the sides' middles),
/// short of the white slivers beside the frame (from 0.625 S), which do
/// not follow the square's axes.
const GRADIENT_RADIUS: f64 = 0.6;

/// Smallest magnitude of the gradients' fourth harmonic as a share of
/// their total weight (squared grey levels): below it the directions do
/// not agree on a rotation (a blank disc, a grey blob) and no quad is
/// made.
const MIN_HARMONIC_SHARE: f64 = 0.05;

/// Samples per side of the grid over the tag plane's `[-1, 1]` square
/// (units of S) that [`looks_printed`] reads the zones' grey levels on.
const LOOK_GRID: usize = 24;

/// The zones of the printed tag [`looks_printed`] compares, by radius in
/// units of S, whatever the tag's rotation: the middle of the data square
/// (cells, under 0.4), ...
const INSIDE_RADIUS: f64 = 0.4;
/// ... the black ring between the white disc (0.71) and the rim (0.82),
/// ...
const BLACK_RING: (f64, f64) = (0.74, 0.79);
/// ... and the white annulus outside the rim (0.82-0.95).
const ANNULUS: (f64, f64) = (0.87, 0.92);

/// Smallest step (grey levels) from the black ring's level to the
/// annulus's.
const MIN_RIM_CONTRAST: f64 = 5.0;

/// Range of the inside's mean level, as a share of the ring-to-annulus
/// step above the ring: the data square's cells, half of them white, are
/// brighter than the black ring and darker than the white paper. A round
/// blob of clutter, dark or bright throughout, is neither. On the wild set
/// a fifth of the rims the rim look tried read a tag or lay in this range;
/// each of the others cost a refinement and a decoding.
const INSIDE_SHARE: (f64, f64) = (0.1, 1.0);

/// Range of the inside's standard deviation, as a share of the
/// ring-to-annulus step: cells black and white in any mix spread by at
/// most half the step (noise and glare add some), and a blur that leaves
/// them any pattern leaves some spread, while a flat blob has none and a
/// shape with strokes across it more than a tag can. On the wild set the
/// rims the rim look read a tag in spread 0.14-0.93; of the others a
/// quarter fell outside, and on the wild benchmark's 1080p frames, whose
/// clutter is discs and rings with strokes, 17 of 28.
const INSIDE_SPREAD: (f64, f64) = (0.1, 1.0);

/// Fewest samples of a zone: a zone partly off the image is read over the
/// rest of it.
const MIN_ZONE_SAMPLES: usize = 8;

/// Whether the tag plane mapped into the image by `at` (units of S, any
/// rotation) shows what a printed tag would at the rim's scale: a black
/// ring inside the rim darker than the paper outside it, and cells
/// between the two ([`INSIDE_SHARE`]) with a tag's spread
/// ([`INSIDE_SPREAD`]). A cheap refusal before the
/// rotation, the refinement and the decoding, for the round shapes of
/// clutter that are no tag.
fn looks_printed(img: &GrayView<'_>, at: &dyn Fn(f64, f64) -> [f64; 2]) -> bool {
    // Sums and counts of the inside, the ring and the annulus.
    let mut zones = [(0.0f64, 0usize); 3];
    // Sum of the inside's squared levels, for its spread.
    let mut sq = 0.0f64;
    let step = 2.0 / LOOK_GRID as f64;
    for i in 0..LOOK_GRID {
        let u = -1.0 + (i as f64 + 0.5) * step;
        for j in 0..LOOK_GRID {
            let v = -1.0 + (j as f64 + 0.5) * step;
            let r = u.hypot(v);
            let zone = if r < INSIDE_RADIUS {
                0
            } else if r > BLACK_RING.0 && r < BLACK_RING.1 {
                1
            } else if r > ANNULUS.0 && r < ANNULUS.1 {
                2
            } else {
                continue;
            };
            let p = at(u, v);
            if let Some(g) = sample_bilinear(img, p[0], p[1]) {
                zones[zone].0 += g;
                zones[zone].1 += 1;
                if zone == 0 {
                    sq += g * g;
                }
            }
        }
    }
    if zones.iter().any(|z| z.1 < MIN_ZONE_SAMPLES) {
        return false;
    }
    let [inside, ring, annulus] = zones.map(|(s, n)| s / n as f64);
    let step = annulus - ring;
    if step < MIN_RIM_CONTRAST {
        return false;
    }
    let share = (inside - ring) / step;
    let sd = (sq / zones[0].1 as f64 - inside * inside).max(0.0).sqrt();
    let spread = sd / step;
    share >= INSIDE_SHARE.0
        && share <= INSIDE_SHARE.1
        && spread >= INSIDE_SPREAD.0
        && spread <= INSIDE_SPREAD.1
}

/// Points around a rim at which [`stands_out`] compares the two sides.
const STAND_OUT_POINTS: usize = 32;

/// Where [`stands_out`] samples inside and outside a rim, as shares of
/// its fitted radii (the border's, without [`RIM_BORDER_OFFSET`]) from its
/// centre: 0.8 in the black disc, 1.15 in the white
/// around it (the annulus and the print's border reach 1.22 of the rim's
/// radius), each clear of the rim's own blurred edge on small tags.
/// Measured on the wild set against 0.88 / 1.08: of the pairs' ellipses at
/// true rims, 92 of 98 kept instead of 85.
const STAND_OUT_RADII: (f64, f64) = (0.8, 1.15);

/// Least median, over the points, of the grey level outside the rim less
/// the level inside (grey levels), ...
const STAND_OUT_MIN_CONTRAST: f64 = 4.0;

/// ... and least share of points where outside is the lighter: a stick
/// across the disc darkens the outside where it leaves, and at 30-40%
/// coverage of a rim's half.
const STAND_OUT_MIN_SHARE: f64 = 0.5;

/// Whether the rim `e` (working coordinates, `scale` full px per working
/// px) is the edge of a dark disc on white in `img`: the median contrast
/// across it and the share of points lighter outside (see
/// [`STAND_OUT_MIN_CONTRAST`], [`STAND_OUT_MIN_SHARE`]). For rims fitted
/// to fragments alone (`ellipses::group_fragments`): on the wild set's
/// 3000 frames, of their ellipses 98 lay at a true rim and 92 of them
/// passed; of the 6394 others, about 1700.
pub(crate) fn stands_out(img: &GrayView<'_>, e: &Ellipse, scale: f64) -> bool {
    let c = to_full(e.centre, scale);
    let (a, b) = (e.a * scale, e.b * scale);
    let (u, v) = (e.axis, [-e.axis[1], e.axis[0]]);
    let mut diffs: Vec<f64> = Vec::with_capacity(STAND_OUT_POINTS);
    for k in 0..STAND_OUT_POINTS {
        let t = std::f64::consts::TAU * k as f64 / STAND_OUT_POINTS as f64;
        let (x, y) = (a * t.cos(), b * t.sin());
        let at = |f: f64| {
            sample_bilinear(
                img,
                c[0] + f * (x * u[0] + y * v[0]),
                c[1] + f * (x * u[1] + y * v[1]),
            )
        };
        if let (Some(inside), Some(outside)) = (at(STAND_OUT_RADII.0), at(STAND_OUT_RADII.1)) {
            diffs.push(outside - inside);
        }
    }
    if diffs.is_empty() {
        return false;
    }
    let lighter = diffs.iter().filter(|&&d| d > 0.0).count() as f64 / diffs.len() as f64;
    diffs.sort_by(f64::total_cmp);
    diffs[diffs.len() / 2] >= STAND_OUT_MIN_CONTRAST && lighter >= STAND_OUT_MIN_SHARE
}

/// The longest and the shortest side (px) the square that rim `e`
/// (working coordinates, `scale` full px per working px) predicts may have
/// ([`rim_quad`]): its axes over the rim's radius, the singular values of
/// the affine map, bound every side's length.
pub(crate) fn side_bounds(e: &Ellipse, scale: f64) -> (f64, f64) {
    let (a, b) = rim_axes(e, scale);
    (a / RIM_RADIUS, b / RIM_RADIUS)
}

/// The semi-axes (full-resolution px) of the printed rim that rim `e`
/// (working coordinates, `scale` full px per working px) was measured on:
/// its fitted axes with the border's half-pixel inset
/// ([`RIM_BORDER_OFFSET`]) put back.
fn rim_axes(e: &Ellipse, scale: f64) -> (f64, f64) {
    (
        (e.a + RIM_BORDER_OFFSET) * scale,
        (e.b + RIM_BORDER_OFFSET) * scale,
    )
}

/// Four corners of a quad (px).
type Quad = [[f64; 2]; 4];

/// The data square of the tag whose disc rim is `e` (working coordinates,
/// `scale` full-resolution px per working px), as four corners on the
/// full-resolution `img`, as the rim and the gradients predict it, in the
/// order TL, BL, BR, TR up to a rotation, with the affine map of the
/// tag's plane that makes them (for [`RimSeen::aligned`]). `None` when
/// the gradients inside do not fix a rotation or the quad does not look
/// like a printed tag's ([`looks_printed`]).
pub(crate) fn rim_quad(img: &GrayView<'_>, e: &Ellipse, scale: f64) -> Option<(Quad, Affine)> {
    let c = to_full(e.anchor, scale);
    let (a, b) = side_bounds(e, scale);
    let (ca, sa) = (e.axis[0], e.axis[1]);
    // M0 = Rot(phi) diag(a, b): tag plane (units of S) to image offsets.
    let m0 = [[ca * a, -sa * b], [sa * a, ca * b]];
    // Its inverse, to bring image offsets back to the tag's plane.
    let inv = [[ca / a, sa / a], [-sa / b, ca / b]];
    let at0 = |u: f64, v: f64| {
        [
            c[0] + m0[0][0] * u + m0[0][1] * v,
            c[1] + m0[1][0] * u + m0[1][1] * v,
        ]
    };
    if !looks_printed(img, &at0) {
        return None;
    }
    let reach = a * GRADIENT_RADIUS + 1.0;
    let (w, h) = (img.width() as i64, img.height() as i64);
    let x0 = ((c[0] - reach).floor() as i64).max(1);
    let x1 = ((c[0] + reach).ceil() as i64).min(w - 2);
    let y0 = ((c[1] - reach).floor() as i64).max(1);
    let y1 = ((c[1] + reach).ceil() as i64).min(h - 2);
    if x0 > x1 || y0 > y1 {
        return None;
    }
    let (mut sx, mut sy, mut total) = (0.0f64, 0.0f64, 0.0f64);
    for y in y0..=y1 {
        let (up, row, down) = (
            img.row(y as usize - 1),
            img.row(y as usize),
            img.row(y as usize + 1),
        );
        for x in x0..=x1 {
            let d = [x as f64 - c[0], y as f64 - c[1]];
            let t = [
                inv[0][0] * d[0] + inv[0][1] * d[1],
                inv[1][0] * d[0] + inv[1][1] * d[1],
            ];
            if norm(t) > GRADIENT_RADIUS {
                continue;
            }
            let xu = x as usize;
            let gx = (row[xu + 1] as f64 - row[xu - 1] as f64) * 0.5;
            let gy = (down[xu] as f64 - up[xu] as f64) * 0.5;
            // The gradient in the tag's plane: the image gradient through
            // M0's transpose (chain rule).
            let tx = m0[0][0] * gx + m0[1][0] * gy;
            let ty = m0[0][1] * gx + m0[1][1] * gy;
            let (c2, s2) = (tx * tx - ty * ty, 2.0 * tx * ty);
            let m2 = tx * tx + ty * ty;
            if m2 <= 0.0 {
                continue;
            }
            // e^{4i alpha} weighted by |g|^2.
            sx += (c2 * c2 - s2 * s2) / m2;
            sy += 2.0 * c2 * s2 / m2;
            total += m2;
        }
    }
    if total <= 0.0 || sx.hypot(sy) < MIN_HARMONIC_SHARE * total {
        return None;
    }
    let psi = sy.atan2(sx) / 4.0;
    let (cp, sp) = (psi.cos(), psi.sin());
    let m = [
        [
            m0[0][0] * cp + m0[0][1] * sp,
            -m0[0][0] * sp + m0[0][1] * cp,
        ],
        [
            m0[1][0] * cp + m0[1][1] * sp,
            -m0[1][0] * sp + m0[1][1] * cp,
        ],
    ];
    let at = |u: f64, v: f64| {
        [
            c[0] + m[0][0] * u + m[0][1] * v,
            c[1] + m[1][0] * u + m[1][1] * v,
        ]
    };
    let predicted = [at(-0.5, -0.5), at(-0.5, 0.5), at(0.5, 0.5), at(0.5, -0.5)];
    Some((predicted, Affine { m, c }))
}

/// The affine map of the tag's plane (units of S) into the image
/// (full-resolution px) that a rim predicts: `c + m (u, v)`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Affine {
    m: [[f64; 2]; 2],
    c: [f64; 2],
}

/// What the rim look saw of a candidate's tag (`quads::Candidate::rim`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct RimSeen {
    /// The disc rim (working coordinates).
    pub ellipse: Ellipse,
    /// The tag's projection the rim and the gradients predict, up to a
    /// quarter turn.
    predicted: Affine,
}

impl RimSeen {
    /// The data square's corners (full-resolution px, TL, BL, BR, TR of
    /// the print) where the print's fixed look aligns to `img` from the
    /// prediction ([`print_align::align`]), if it does. Aligned when the
    /// candidate is decoded rather than when it is made: the alignment is
    /// the rim look's costliest step, and a candidate refused before its
    /// reading, or past the decoding budget, needs none.
    pub(crate) fn aligned(&self, img: &GrayView<'_>) -> Option<Quad> {
        print_align::align(img, self.predicted.m, self.predicted.c)
            .filter(|a| a.correlation >= print_align::MIN_CORRELATION)
            .map(|a| a.corners)
    }
}

/// The candidate quad of rim `e` (working coordinates, `scale` full px per
/// working px), for the decoding stage: its four sides given as the edge
/// pieces refinement measures the sides along (the corners are where the
/// measured sides meet, and the verify stage's model fit judges which the
/// image supports), decoded after every other candidate and never as a
/// rival of a tag already read (`guessed`, as the corners of a
/// parallelogram).
pub(crate) fn rim_candidate(img: &GrayView<'_>, e: &Ellipse, scale: f64) -> Option<Candidate> {
    let (q, predicted) = rim_quad(img, e, scale)?;
    let (w, edges) = sides_of(&q, scale);
    let area = 0.5
        * ((w[2][0] - w[0][0]) * (w[3][1] - w[1][1]) - (w[3][0] - w[1][0]) * (w[2][1] - w[0][1]))
            .abs();
    Some(Candidate {
        corners: w,
        estimated: [false; 4],
        edges,
        anchor: Some(e.anchor),
        real: 4,
        area,
        linked: false,
        guessed: true,
        rim: Some(RimSeen {
            ellipse: *e,
            predicted,
        }),
    })
}

/// Rim candidate `cand` moved onto the quad `q` (full-resolution px):
/// its corners and its four sides, the edge pieces refinement measures
/// the sides along, are `q`'s. For refining the aligned print's square
/// instead of the rim's prediction.
pub(crate) fn moved_to(cand: &Candidate, q: &Quad, scale: f64) -> Candidate {
    let (corners, edges) = sides_of(q, scale);
    Candidate {
        corners,
        edges,
        ..*cand
    }
}

/// The corners of the full-resolution quad `q` in working coordinates
/// (`scale` full px per working px) and its four sides as each corner's
/// incoming and outgoing edge pieces.
fn sides_of(q: &Quad, scale: f64) -> (Quad, [Option<Edges>; 4]) {
    let o = (scale - 1.0) / 2.0;
    let w = q.map(|p| [(p[0] - o) / scale, (p[1] - o) / scale]);
    let edges = std::array::from_fn(|k| {
        Some(Edges {
            incoming: [w[(k + 3) % 4], w[k]],
            outgoing: [w[k], w[(k + 1) % 4]],
        })
    });
    (w, edges)
}

/// Points of the printed rim checked against the measured one by
/// [`rim_disagreement`].
const RIM_CHECK_POINTS: usize = 32;

/// How far (px) the disc rim that homography `h` (tag units, S = 1) puts
/// on the image strays from the measured rim `e` (working coordinates,
/// `scale` full px per working px), at most over [`RIM_CHECK_POINTS`]
/// points, as a share of the mean side of the data square `h` makes.
/// A reading whose corners came from the rim must put the disc back where
/// it was seen: a fit that took an occluder's edge for a side moves it.
pub(crate) fn rim_disagreement(h: &Homography, e: &Ellipse, scale: f64) -> f64 {
    let c = to_full(e.centre, scale);
    let (a, b) = rim_axes(e, scale);
    let (ca, sa) = (e.axis[0], e.axis[1]);
    let [Some(p0), Some(p1), Some(p2), Some(p3)] = crate::geometry::CORNERS.map(|p| h.map(p))
    else {
        return f64::INFINITY;
    };
    let side = mean_side(&[p0, p1, p2, p3]);
    let mut worst = 0.0f64;
    for k in 0..RIM_CHECK_POINTS {
        let t = std::f64::consts::TAU * k as f64 / RIM_CHECK_POINTS as f64;
        let Some(p) = h.map([RIM_RADIUS * t.cos(), RIM_RADIUS * t.sin()]) else {
            return f64::INFINITY;
        };
        let d = [p[0] - c[0], p[1] - c[1]];
        // The point in the measured rim's frame, where the rim is the unit
        // circle: its radius there less one, times the rim's mean radius,
        // is about its distance from the rim.
        let u = (d[0] * ca + d[1] * sa) / a;
        let v = (-d[0] * sa + d[1] * ca) / b;
        worst = worst.max(((u.hypot(v) - 1.0) * (a * b).sqrt()).abs());
    }
    if side > 0.0 {
        worst / side
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::family::Family;
    use crate::grid_code::encode_cells;
    use crate::math::sub;
    use image::GrayImage;

    const SIDE: f64 = 60.0;
    const CENTRE: [f64; 2] = [100.0, 100.0];

    /// The affine map of a tag of side `SIDE` at `CENTRE` turned by
    /// `turn`, foreshortened by `k` along direction `phi`: tag units to
    /// image offsets.
    fn affine(turn: f64, k: f64, phi: f64) -> [[f64; 2]; 2] {
        let rot = |a: f64| [[a.cos(), -a.sin()], [a.sin(), a.cos()]];
        let mul = |a: [[f64; 2]; 2], b: [[f64; 2]; 2]| {
            std::array::from_fn(|i| std::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j]))
        };
        let d = [[SIDE, 0.0], [0.0, SIDE * k]];
        mul(mul(rot(phi), d), mul(rot(-phi), rot(turn)))
    }

    /// A 200 x 200 image of ct14 tag 77 through `m`: the black disc to the
    /// rim on a white page, the black frame, the white margin and the
    /// cells (the slivers and the checker left out), box-blurred once so
    /// that edges are not aliased; and the rim as the ellipse stage would
    /// report it.
    fn tag(m: [[f64; 2]; 2], plain: bool) -> (GrayImage, Ellipse, [[f64; 2]; 4]) {
        let fam = Family::ct14();
        let n = fam.grid();
        let cells = encode_cells(fam, 77).unwrap();
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        let inv = [
            [m[1][1] / det, -m[0][1] / det],
            [-m[1][0] / det, m[0][0] / det],
        ];
        let sharp = GrayImage::from_fn(200, 200, |x, y| {
            let d = [f64::from(x) - CENTRE[0], f64::from(y) - CENTRE[1]];
            let (u, v) = (
                inv[0][0] * d[0] + inv[0][1] * d[1],
                inv[1][0] * d[0] + inv[1][1] * d[1],
            );
            let mx = u.abs().max(v.abs());
            let black = if u.hypot(v) > RIM_RADIUS {
                false
            } else if plain || mx > 0.5 {
                true
            } else {
                crate::test_images::data_black(&cells, n, u, v)
            };
            image::Luma([if black { 30 } else { 220 }])
        });
        let img = imageproc::filter::box_filter(&sharp, 1, 1);
        // The rim's axes: the singular values of `m` times the rim radius,
        // less the border offset the ellipse stage's borders show.
        let (a, b, c) = (m[0][0], m[0][1], m[1][0]);
        let dd = m[1][1];
        let (s1, s2) = {
            let p = a * a + b * b + c * c + dd * dd;
            let q =
                ((a * a + b * b - c * c - dd * dd).powi(2) + 4.0 * (a * c + b * dd).powi(2)).sqrt();
            (((p + q) / 2.0).sqrt(), ((p - q) / 2.0).sqrt())
        };
        // Major axis: the left singular vector of the larger value.
        let th = 0.5 * (2.0 * (a * c + b * dd)).atan2(a * a + b * b - c * c - dd * dd);
        let e = Ellipse {
            centre: CENTRE,
            a: s1 * RIM_RADIUS - RIM_BORDER_OFFSET,
            b: s2 * RIM_RADIUS - RIM_BORDER_OFFSET,
            anchor: CENTRE,
            checker: false,
            axis: [th.cos(), th.sin()],
            pieced: false,
        };
        let corners = crate::geometry::CORNERS.map(|[u, v]| {
            [
                CENTRE[0] + m[0][0] * u + m[0][1] * v,
                CENTRE[1] + m[1][0] * u + m[1][1] * v,
            ]
        });
        (img, e, corners)
    }

    /// Largest corner distance (px) of `q` from `truth` over the four
    /// cyclic orders (the rotation modulo 90 degrees is all `rim_quad`
    /// gives).
    fn off(q: &[[f64; 2]; 4], truth: &[[f64; 2]; 4]) -> f64 {
        (0..4)
            .map(|r| {
                (0..4)
                    .map(|k| norm(sub(q[(k + r) % 4], truth[k])))
                    .fold(0.0, f64::max)
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn the_rim_and_the_gradients_place_the_square() {
        for (turn, k, phi) in [
            (0.3, 1.0, 0.0),
            (1.1, 0.7, 0.4),
            (-0.6, 0.55, 2.0),
            (2.5, 0.85, -1.0),
        ] {
            let (img, e, truth) = tag(affine(turn, k, phi), false);
            let (q, _) = rim_quad(&GrayView::from(&img), &e, 1.0).expect("a quad");
            // Within 4% of the side: what refinement's windows reach.
            assert!(
                off(&q, &truth) < 0.04 * SIDE,
                "turn {turn}: {q:?} vs {truth:?}"
            );
        }
    }

    #[test]
    fn a_rim_stands_out_where_a_dark_disc_meets_white() {
        let (img, e, _) = tag(affine(1.1, 0.7, 0.4), false);
        assert!(stands_out(&GrayView::from(&img), &e, 1.0));
        // The same rim over a light disc on grey, and over a flat grey.
        let c = e.centre;
        let inside = |x: u32, y: u32| {
            let (dx, dy) = (f64::from(x) - c[0], f64::from(y) - c[1]);
            let (u, v) = (
                dx * e.axis[0] + dy * e.axis[1],
                -dx * e.axis[1] + dy * e.axis[0],
            );
            (u / e.a).powi(2) + (v / e.b).powi(2) <= 1.0
        };
        let light = GrayImage::from_fn(img.width(), img.height(), |x, y| {
            image::Luma([if inside(x, y) { 220 } else { 90 }])
        });
        assert!(!stands_out(&GrayView::from(&light), &e, 1.0));
        let flat = GrayImage::from_pixel(img.width(), img.height(), image::Luma([128]));
        assert!(!stands_out(&GrayView::from(&flat), &e, 1.0));
        // A dark bar across half the rim leaves the rest to show it.
        let barred = GrayImage::from_fn(img.width(), img.height(), |x, y| {
            let p = img.get_pixel(x, y)[0];
            image::Luma([if f64::from(y) > c[1] + 8.0 { 30 } else { p }])
        });
        assert!(stands_out(&GrayView::from(&barred), &e, 1.0));
    }

    #[test]
    fn a_plain_dark_disc_is_no_tag() {
        let (img, e, _) = tag(affine(0.3, 0.8, 0.5), true);
        assert!(rim_quad(&GrayView::from(&img), &e, 1.0).is_none());
    }

    #[test]
    fn a_fit_that_moves_the_rim_disagrees_with_it() {
        let m = affine(0.7, 0.75, 1.2);
        let (_, e, truth) = tag(m, false);
        let h = Homography::from_points(&crate::geometry::CORNERS, &truth).unwrap();
        assert!(rim_disagreement(&h, &e, 1.0) < 0.02);
        // The square a fifth larger: its rim 0.16 S (10 px) outside.
        let big = truth.map(|p| {
            [
                CENTRE[0] + 1.2 * (p[0] - CENTRE[0]),
                CENTRE[1] + 1.2 * (p[1] - CENTRE[1]),
            ]
        });
        let h = Homography::from_points(&crate::geometry::CORNERS, &big).unwrap();
        assert!(rim_disagreement(&h, &e, 1.0) > 0.1);
    }
}
