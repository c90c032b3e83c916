//! The blur bias of a data-square side measured by its half-level
//! crossing, computed on a model of the side and taken off the measure.
//!
//! Refinement (stage 6) and the decoded tag's fit (stage 7) place each
//! side where the grey profile across it crosses halfway between the
//! brightest sample on the white side of the window and the darkest on
//! the black side. For a lone step edge under a symmetric blur that is
//! exactly the printed edge. A data square's side is no lone edge: the
//! white margin inside it is one cell wide, and the cells beyond it are
//! half black. Once the blur reaches across the margin, the margin's
//! brightest sample sinks towards grey, the half level sinks with it, and
//! the crossing moves outwards, into the black frame: every side of a
//! blurred tag is measured too far out, and the quad comes out too large.
//! On the wild benchmark's unoccluded, unglared tags of 32-48 px the
//! corners lay 0.28 px (moderate blur) and 0.46 px (strong blur) too far
//! from the tag centre on average, against 0.00 px on sharp tags; at the
//! true corners moved 0.3 px outwards the decoder read 2 points fewer of
//! the benchmark's main subset, at 0.6 px 6 points fewer.
//!
//! The bias depends only on the blur's width against the margin's, and
//! the same ruler measuring a model of the side shows it: the profile of
//! a margin one cell wide between the black frame and cells of mean
//! whiteness one half ([`CELLS_WHITENESS`]), under a Gaussian blur,
//! sampled and read exactly as the image is ([`Ruler`]). The blur's width
//! is found the same way, from the measured width of the profiles' rise
//! (a quarter to three quarters of the step): the model's rise, read by
//! the same ruler, is matched to it. Sides are then moved inwards by the
//! model's crossing offset at that blur. (A moving camera's blur is a
//! line, not a Gaussian; matched by the width of its rise, the Gaussian
//! model stands in for it.)

/// Mean whiteness of the cells next to the margin, in the model: the
/// cells of both families are black exactly when their bit differs from a
/// checkerboard mask, so about half of any row of them is black.
const CELLS_WHITENESS: f64 = 0.5;

/// Distance between the quartiles of a Gaussian, in its sigmas (2 x
/// 0.6745): a lone edge blurred by a Gaussian of sigma b rises from a
/// quarter to three quarters of its step over 1.349 b.
pub(crate) const GAUSS_QUARTILE_SPAN: f64 = 1.349;

/// Narrowest blur (px, Gaussian sigma) of the model; a sharper profile's
/// rise is the sampling's, not the blur's.
const MIN_SIGMA: f64 = 0.2;

/// Widest blur (px) the model is matched up to, in cells: beyond about
/// a cell and a half the cells themselves can no longer be read, and the
/// measuring windows no longer hold the rise.
const MAX_SIGMA_CELLS: f64 = 1.5;

/// Finest model sampling step (px): a profile with a coarser step is read
/// with that step, as the image's profile is.
const MODEL_STEP: f64 = 0.25;

/// How a side's profile is read: the window on the white side (inside
/// the data square) and on the black side (px), and the sampling step.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ruler {
    /// Window on the white side (px).
    pub white: f64,
    /// Window on the black side (px).
    pub black: f64,
    /// Sampling step (px).
    pub step: f64,
}

/// The standard normal distribution function. `libm`'s `erf`: the
/// standard library has none on stable Rust.
fn phi(x: f64) -> f64 {
    0.5 * (1.0 + libm::erf(x * std::f64::consts::FRAC_1_SQRT_2))
}

/// Whiteness (black 0, white 1) across a side at `s` px outwards of the
/// printed edge: margin `cell` px wide inside it, cells of mean whiteness
/// [`CELLS_WHITENESS`] beyond, black outside, blurred by `sigma`.
fn model(s: f64, sigma: f64, cell: f64) -> f64 {
    let into_cells = phi((-cell - s) / sigma);
    phi(-s / sigma) - into_cells + CELLS_WHITENESS * into_cells
}

/// What the ruler reads on the model's profile at blur `sigma`: the
/// half-level crossing's offset (px, positive outwards) and the rise's
/// width (px). `None` where the window shows no crossing.
fn read_model(sigma: f64, cell: f64, r: &Ruler) -> Option<(f64, f64)> {
    let step = r.step.max(MODEL_STEP);
    let k0 = -(r.white / step).round() as i32;
    let k1 = (r.black / step).round() as i32;
    let prof: Vec<f64> = (k0..=k1)
        .map(|k| model(f64::from(k) * step, sigma, cell))
        .collect();
    let mid = (-k0) as usize;
    let (white, black) = levels(&prof, mid);
    // The model's profile rises over the margin and falls once into the
    // frame: its one falling crossing is the one nearest the edge.
    let (_, at) = falling_crossing(&prof, 0.5 * (white + black), mid, step)?;
    let width = rise_width(&prof, black, white - black, at);
    Some(((at - mid as f64) * step, width * step))
}

/// The white and black levels of a profile across a side whose printed
/// edge is expected at sample `mid`: the brightest sample up to it and the
/// darkest from it. Refinement, the model fit and the model of the side
/// all read their profiles this way.
pub(crate) fn levels(prof: &[f64], mid: usize) -> (f64, f64) {
    let white = prof[..=mid].iter().copied().fold(f64::MIN, f64::max);
    let black = prof[mid..].iter().copied().fold(f64::MAX, f64::min);
    (white, black)
}

/// Where `prof` (samples `step` px apart, the expected edge at sample
/// `mid`) falls through `level`, the falling crossing nearest the
/// expected edge: its offset from it (px, positive towards the end of the
/// profile) and its position in samples. `None` without one.
pub(crate) fn falling_crossing(
    prof: &[f64],
    level: f64,
    mid: usize,
    step: f64,
) -> Option<(f64, f64)> {
    let start = -(mid as f64);
    let mut best: Option<(f64, f64)> = None;
    for i in 0..prof.len().saturating_sub(1) {
        let (u, v) = (prof[i], prof[i + 1]);
        if u >= level && v < level {
            let f = (u - level) / (u - v);
            let off = (start + i as f64 + f) * step;
            if best.is_none_or(|(b, _)| off.abs() < b.abs()) {
                best = Some((off, i as f64 + f));
            }
        }
    }
    best
}

/// Width (in profile samples) of the rise of the falling edge of `prof`
/// whose half-level crossing is at sample position `at`: from where the
/// profile last lies above three quarters of the step `span` over `black`
/// before it, to where it first lies below a quarter after it.
pub(crate) fn rise_width(prof: &[f64], black: f64, span: f64, at: f64) -> f64 {
    let (hi, lo) = (black + 0.75 * span, black + 0.25 * span);
    let i0 = (at.floor().max(0.0) as usize).min(prof.len() - 1);
    // Back towards the white side for the three-quarter crossing.
    let mut start = 0.0;
    for i in (0..i0.min(prof.len() - 1)).rev() {
        if prof[i] >= hi {
            let f = (prof[i] - hi) / (prof[i] - prof[i + 1]).max(1e-12);
            start = i as f64 + f.clamp(0.0, 1.0);
            break;
        }
    }
    // On towards the black side for the quarter crossing.
    let mut end = (prof.len() - 1) as f64;
    for i in i0..prof.len() - 1 {
        if prof[i + 1] <= lo {
            let f = (prof[i] - lo) / (prof[i] - prof[i + 1]).max(1e-12);
            end = i as f64 + f.clamp(0.0, 1.0);
            break;
        }
    }
    (end - start).max(0.0)
}

/// The bias of one candidate's sides as a function of the rise the
/// profiles show: the model read at [`TABLE_SIGMAS`] blurs from
/// [`MIN_SIGMA`] to [`MAX_SIGMA_CELLS`], by the ruler the rise is measured
/// with and by the ruler the side is placed with. Built once per tag
/// (its cell and rulers are the same on its four sides) and looked up by
/// linear interpolation: a side costs nothing more.
#[derive(Debug, Clone)]
pub(crate) struct BlurBias {
    rise: [f64; TABLE_SIGMAS],
    bias: [f64; TABLE_SIGMAS],
}

/// Blurs at which [`BlurBias`] reads the model, evenly spaced: the bias
/// and the rise are smooth in the blur, within a hundredth of a pixel of
/// their linear interpolation between these.
const TABLE_SIGMAS: usize = 9;

impl BlurBias {
    /// The table for a margin `cell` px wide, whose sides' rise is
    /// measured with `measure` and whose sides are placed with `place`.
    /// `None` for a degenerate cell or ruler.
    pub(crate) fn new(cell: f64, measure: &Ruler, place: &Ruler) -> Option<Self> {
        if !(cell > 0.0 && cell.is_finite() && measure.step > 0.0 && place.step > 0.0) {
            return None;
        }
        let top = (MAX_SIGMA_CELLS * cell).max(MIN_SIGMA);
        let mut t = Self {
            rise: [0.0; TABLE_SIGMAS],
            bias: [0.0; TABLE_SIGMAS],
        };
        for k in 0..TABLE_SIGMAS {
            let sigma = MIN_SIGMA + (top - MIN_SIGMA) * k as f64 / (TABLE_SIGMAS - 1) as f64;
            t.rise[k] = read_model(sigma, cell, measure)?.1;
            // At the narrowest blur the margin is untouched.
            t.bias[k] = if k == 0 {
                0.0
            } else {
                read_model(sigma, cell, place).map_or(0.0, |(at, _)| at)
            };
        }
        Some(t)
    }

    /// How far outwards (px) the side lies whose profiles rise over
    /// `width` px: interpolated on the first stretch of the table whose
    /// rises bracket it (the rise stops growing once the blur outgrows the
    /// measuring window), clamped at the table's ends.
    pub(crate) fn at(&self, width: f64) -> f64 {
        if width.is_nan() || width <= self.rise[0] {
            return self.bias[0];
        }
        for k in 1..TABLE_SIGMAS {
            let (r0, r1) = (self.rise[k - 1], self.rise[k]);
            if width <= r1 && r1 > r0 {
                let f = (width - r0) / (r1 - r0);
                return self.bias[k - 1] + f * (self.bias[k] - self.bias[k - 1]);
            }
        }
        self.bias[TABLE_SIGMAS - 1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const NARROW: Ruler = Ruler {
        white: 1.4,
        black: 1.4,
        step: 0.25,
    };
    const WIDE: Ruler = Ruler {
        white: 3.6,
        black: 5.2,
        step: 0.5,
    };

    /// The model's bias at blur `sigma` (px), read with `r`.
    fn bias_at(sigma: f64, cell: f64, r: &Ruler) -> f64 {
        read_model(sigma, cell, r).unwrap().0
    }

    #[test]
    fn a_sharp_side_has_no_bias() {
        assert!(bias_at(0.2, 2.0, &NARROW).abs() < 0.01);
        assert!(bias_at(0.3, 3.0, &NARROW).abs() < 0.01);
        let t = BlurBias::new(2.0, &WIDE, &NARROW).unwrap();
        assert_eq!(t.at(0.0), 0.0);
        assert_eq!(t.at(f64::NAN), 0.0);
    }

    #[test]
    fn a_blurred_side_is_read_outwards_more_as_the_margin_narrows() {
        // Worked out by hand: at sigma 1 px and a 2 px margin, the
        // margin's peak sinks to about 0.66 and the half level to 0.33,
        // where the profile lies about 0.17 px outside the edge.
        let b = bias_at(1.0, 2.0, &NARROW);
        assert!((0.12..0.22).contains(&b), "{b}");
        // A wide margin is a lone edge again.
        assert!(bias_at(1.0, 8.0, &NARROW).abs() < 0.02);
        assert!(bias_at(1.0, 2.0, &NARROW) > bias_at(1.0, 4.0, &NARROW));
    }

    #[test]
    fn the_table_gives_the_bias_of_the_blur_that_made_the_rise() {
        let t = BlurBias::new(2.0, &WIDE, &NARROW).unwrap();
        for sigma in [0.5, 0.8, 1.2, 1.6, 2.4] {
            let (_, width) = read_model(sigma, 2.0, &WIDE).unwrap();
            let (want, got) = (bias_at(sigma, 2.0, &NARROW), t.at(width));
            assert!((want - got).abs() < 0.01, "sigma {sigma}: {want} vs {got}");
        }
        // Beyond the model's range: clamped, never extrapolated.
        assert_eq!(t.at(100.0), bias_at(3.0, 2.0, &NARROW));
        assert!(BlurBias::new(0.0, &WIDE, &NARROW).is_none());
        assert!(BlurBias::new(f64::NAN, &WIDE, &NARROW).is_none());
    }
}
