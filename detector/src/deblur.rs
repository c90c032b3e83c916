//! Reading the cells of a blurred tag: undoing the blur in cell space.
//!
//! Defocus spreads each cell's ink over its neighbours. Once the blur is
//! about half a cell wide, an isolated black cell in white ones samples
//! lighter than the threshold (and the other way round), and the plain
//! reading fails although the grid is still visibly there. The tag's
//! layout is known around the grid (a white one-cell margin, then the
//! black frame), and a Gaussian blur of width `sigma` cells makes every
//! cell's sample a fixed mix of its own colour and its neighbours'. So the
//! cells' colours are the solution of a small linear system; the blur is
//! separable, so that is two products with the inverse of an `n` x `n`
//! banded matrix (regularised against noise), a few microseconds.
//!
//! The blur model is the one of the paper's defocus discussion and of any
//! camera simulator (a Gaussian point spread); the method is plain
//! linear deconvolution, not taken from any other detector.

use nalgebra::DMatrix;

/// Largest neighbour offset (cells) the blur model looks at: a Gaussian of
/// 0.8 cells puts under 0.2% of its weight beyond 2.5 cells.
const REACH: i64 = 2;

/// Sub-samples per cell when integrating the Gaussian over a cell.
const SUBSAMPLES: usize = 8;

/// Tikhonov weight added to the blur matrix's diagonal before inverting
/// it: the blur's weakest mode (cells alternating black and white) is
/// damped by as little as 0.1 at the widest blur tried, so the plain
/// inverse would multiply the noise there tenfold per axis.
const RIDGE: f64 = 0.05;

/// Weight of a neighbour `d` cells away along one axis for a Gaussian of
/// `sigma` cells: its mass over that cell (midpoint rule), normalised over
/// the offsets `-REACH..=REACH`.
fn axis_weights(sigma: f64) -> [f64; (2 * REACH + 1) as usize] {
    let w = cell_weights(sigma, REACH);
    std::array::from_fn(|k| w[k])
}

/// Weights of the offsets `-reach..=reach` (cells) along one axis for a
/// Gaussian blur of `sigma` cells: each offset's mass over its cell
/// (midpoint rule with [`SUBSAMPLES`] points), normalised to sum to one.
/// `sigma` 0 is no blur.
pub(crate) fn cell_weights(sigma: f64, reach: i64) -> Vec<f64> {
    let mut w = vec![0.0; (2 * reach + 1) as usize];
    if sigma <= 0.0 {
        w[reach as usize] = 1.0;
        return w;
    }
    for (k, wk) in w.iter_mut().enumerate() {
        let d = k as f64 - reach as f64;
        *wk = (0..SUBSAMPLES)
            .map(|t| {
                let x = d - 0.5 + (t as f64 + 0.5) / SUBSAMPLES as f64;
                (-x * x / (2.0 * sigma * sigma)).exp()
            })
            .sum();
    }
    let total: f64 = w.iter().sum();
    for v in &mut w {
        *v /= total;
    }
    w
}

/// The forward model: whiteness of an `n` x `n` grid of cells `x`
/// (row-major, 0 black, 1 white) as sampled through a Gaussian blur of
/// `sigma` cells that reaches `reach` cells, with the tag's white margin
/// and black frame around the grid ([`outside`]).
pub(crate) fn blur_grid(x: &[f64], n: usize, sigma: f64, reach: i64) -> Vec<f64> {
    let w = cell_weights(sigma, reach);
    let ni = n as i64;
    let at = |a: i64, b: i64| {
        if (0..ni).contains(&a) && (0..ni).contains(&b) {
            x[(a * ni + b) as usize]
        } else {
            outside(a, b, ni)
        }
    };
    let mut out = Vec::with_capacity(n * n);
    for i in 0..ni {
        for j in 0..ni {
            let mut s = 0.0;
            for di in -reach..=reach {
                for dj in -reach..=reach {
                    s += w[(di + reach) as usize] * w[(dj + reach) as usize] * at(i + di, j + dj);
                }
            }
            out.push(s);
        }
    }
    out
}

/// Whiteness of the tag around an `n` x `n` grid at cell `(i, j)` outside
/// it: the one-cell margin ring is white, everything beyond it black (the
/// frame).
pub(crate) fn outside(i: i64, j: i64, n: i64) -> f64 {
    if (-1..=n).contains(&i) && (-1..=n).contains(&j) {
        1.0
    } else {
        0.0
    }
}

/// The whiteness (0 black, 1 white, clamped) of each of the `n` x `n`
/// cells whose normalised samples are `y` (row-major, 0 at the frame's
/// black, 1 at the margin's white), assuming a Gaussian blur of `sigma`
/// cells. The blur is separable, `Y = A X A^T + C` with `A` the banded
/// one-axis blur of the grid and `C` what the known margin and frame add,
/// so `X = M (Y - C) M^T` with `M = (A + RIDGE I)^-1`: two small matrix
/// products. `None` if the matrix cannot be inverted.
pub(crate) fn deblur(y: &[f64], n: usize, sigma: f64) -> Option<Vec<f64>> {
    let ops = operators(n, sigma)?;
    let ym = DMatrix::from_row_slice(n, n, y);
    let x = &ops.m * (ym - &ops.known) * &ops.mt;
    let mut out = Vec::with_capacity(n * n);
    for i in 0..n {
        for j in 0..n {
            out.push(x[(i, j)].clamp(0.0, 1.0));
        }
    }
    Some(out)
}

/// [`Operators`] as made: `None` where the blur matrix cannot be inverted.
type Made = Option<std::rc::Rc<Operators>>;

/// What [`deblur`] applies for one grid size and blur width, which no
/// sample changes: `M`, its transpose, and `C` (see [`deblur`]).
struct Operators {
    m: DMatrix<f64>,
    mt: DMatrix<f64>,
    known: DMatrix<f64>,
}

thread_local! {
    /// The [`Operators`] made so far on this thread, by grid size and the
    /// blur width's bits: a handful (the decoder tries three widths on
    /// each family's grid). Made once rather than at every call, where
    /// the inverse and the margin's share were made again for every grid
    /// that looked blurred, clutter's included: `deblur` was 3.9% of the
    /// wild set's detection time, and the median time per frame over 600
    /// of its frames fell by 4% (5.85 -> 5.53 ms, interleaved runs), the
    /// same detections. Per thread, so that no lock is taken.
    static OPERATORS: std::cell::RefCell<Vec<(usize, u64, Made)>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// The [`Operators`] of an `n` x `n` grid under a blur of `sigma` cells,
/// made on this thread's first call for them; `None` if the blur matrix
/// cannot be inverted.
fn operators(n: usize, sigma: f64) -> Made {
    let key = (n, sigma.to_bits());
    if let Some(found) = OPERATORS.with_borrow(|ops| {
        ops.iter()
            .find(|(k, s, _)| (*k, *s) == key)
            .map(|(_, _, o)| o.clone())
    }) {
        return found;
    }
    let made = make_operators(n, sigma).map(std::rc::Rc::new);
    OPERATORS.with_borrow_mut(|ops| ops.push((key.0, key.1, made.clone())));
    made
}

/// [`Operators`] computed.
fn make_operators(n: usize, sigma: f64) -> Option<Operators> {
    let w = axis_weights(sigma);
    let ni = n as i64;
    let a = DMatrix::from_fn(n, n, |i, j| {
        let d = j as i64 - i as i64;
        if d.abs() <= REACH {
            w[(d + REACH) as usize] + if d == 0 { RIDGE } else { 0.0 }
        } else {
            0.0
        }
    });
    let m = a.try_inverse()?;
    let known = DMatrix::from_fn(n, n, |i, j| {
        let (i, j) = (i as i64, j as i64);
        let mut c = 0.0;
        for di in -REACH..=REACH {
            for dj in -REACH..=REACH {
                let (p, q) = (i + di, j + dj);
                if !((0..ni).contains(&p) && (0..ni).contains(&q)) {
                    c += w[(di + REACH) as usize] * w[(dj + REACH) as usize] * outside(p, q, ni);
                }
            }
        }
        c
    });
    let mt = m.transpose();
    Some(Operators { m, mt, known })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Blurs a grid of cells (with its margin and frame) as the model says.
    fn blur(cells: &[f64], n: usize, sigma: f64) -> Vec<f64> {
        blur_grid(cells, n, sigma, REACH)
    }

    #[test]
    fn weights_are_symmetric_and_sum_to_one() {
        let w = axis_weights(0.6);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!((w[0] - w[4]).abs() < 1e-12 && (w[1] - w[3]).abs() < 1e-12);
        assert!(w[2] > w[1] && w[1] > w[0]);
    }

    #[test]
    fn a_blurred_grid_is_read_back() {
        // A checkerboard-ish pattern with isolated cells: the hardest case
        // for a plain threshold under blur.
        let n = 8;
        let cells: Vec<f64> = (0..n * n)
            .map(|k| f64::from(u8::from((k * 7 + k / n) % 3 == 0)))
            .collect();
        let y = blur(&cells, n, 0.7);
        let plain_errors = y
            .iter()
            .zip(&cells)
            .filter(|(v, c)| (**v > 0.5) != (**c > 0.5))
            .count();
        assert!(
            plain_errors > 0,
            "the test pattern must defeat a plain threshold"
        );
        let x = deblur(&y, n, 0.7).unwrap();
        for (k, (v, c)) in x.iter().zip(&cells).enumerate() {
            assert_eq!(*v > 0.5, *c > 0.5, "cell {k}: {v:.2} for {c}");
        }
    }

    /// The operators made once per grid size and width serve later calls
    /// of either size as the first did: grids of 8 and 14 cells at the
    /// same widths, interleaved, read back, each call the same to the
    /// bit as the one before it and as operators made afresh.
    #[test]
    fn operators_made_once_serve_every_grid_size() {
        for round in 0..2 {
            for n in [8usize, 14] {
                for sigma in [0.45, 0.6, 0.75] {
                    let cells: Vec<f64> = (0..n * n)
                        .map(|k| f64::from(u8::from((k * 5 + k / n + n) % 3 == 0)))
                        .collect();
                    let y = blur(&cells, n, sigma);
                    let x = deblur(&y, n, sigma).unwrap();
                    for (k, (v, c)) in x.iter().zip(&cells).enumerate() {
                        assert_eq!(*v > 0.5, *c > 0.5, "n {n} sigma {sigma} cell {k}");
                    }
                    let fresh = make_operators(n, sigma).unwrap();
                    let ym = DMatrix::from_row_slice(n, n, &y);
                    let want = &fresh.m * (ym - &fresh.known) * &fresh.mt;
                    let want: Vec<f64> = (0..n * n)
                        .map(|k| want[(k / n, k % n)].clamp(0.0, 1.0))
                        .collect();
                    assert_eq!(x, want, "round {round} n {n} sigma {sigma}");
                }
            }
        }
        // Made once each: two sizes at three widths (the thread may have
        // made others for other tests).
        let made = OPERATORS.with_borrow(|ops| {
            ops.iter()
                .filter(|(n, s, _)| {
                    [8, 14].contains(n) && [0.45f64, 0.6, 0.75].map(f64::to_bits).contains(s)
                })
                .count()
        });
        assert_eq!(made, 6);
    }
}
