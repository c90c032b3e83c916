//! Reading a blurred tag by likelihood: the cells against every codeword.
//!
//! The hard reading thresholds each cell and hands the bits to the
//! Reed-Solomon decoder, which fails once more than its capacity of
//! symbols is misread. On a small, defocused or motion-blurred tag (cells
//! of 1.5 to 3 px under a blur of one to two px) most cells sample grey and
//! a third of the symbols come out wrong, yet the grid still carries
//! nearly all its information: each cell's sample is a known mix of its
//! own colour and its neighbours' ([`crate::deblur`]'s blur model).
//!
//! A family with few ids has few codewords (ct14: 256 ids at 4 rotations),
//! so instead of deciding cell by cell, the whole grid of samples is
//! compared with every codeword as the blur would show it, at a few blur
//! widths: the maximum-likelihood reading under Gaussian noise, with the
//! tag's contrast and black level fitted per codeword by least squares.
//! The reading stands only when the best codeword fits clearly better than
//! the best one of any other id ([`MIN_RATIO`]); a codeword's fit is
//! scored on the cells that fit it best ([`TRIM_KEEP`]), so a few cells
//! hidden by an occluder or a glare spot do not sink the right one.
//! Correlation decoding against a known codebook is textbook
//! (maximum-likelihood decoding, e.g. Lin & Costello, "Error Control
//! Coding", ch. 1); the blur-aware codeword templates are this crate's
//! own.

use crate::deblur::{blur_grid, cell_weights};
use crate::family::Family;
use crate::grid_code::{encode_cells, rotate_cell};

/// Blur widths (Gaussian sigma, in cells) of the codeword templates: from
/// a slightly soft tag to a blur of 1.3 cells, past which a 14-cell grid's
/// alternating cells keep under 1% of their contrast. On the wild set,
/// with the tags' true corners, the widest of an earlier set (0 to 1.0)
/// read the most blurred tags, so the range goes a step beyond it.
pub(crate) const SIGMAS: [f64; 7] = [0.45, 0.6, 0.75, 0.9, 1.05, 1.2, 1.35];

/// Index in [`SIGMAS`] of the blur every codeword is first scored at: the
/// middle of the range, where most blurred tags on the wild set fit best.
const COARSE_SIGMA: usize = 3;

/// The first round's best id must fit better than the second by this
/// factor (ratio of plain scores) for the finer rounds to run: most quads
/// that are no tag fit many ids about equally. With the tags' true
/// corners on the wild set, every reading had a first-round ratio of 0.19
/// or less, and all but 7 of those worth aligning ([`PROMISING_RATIO`])
/// 0.6 or less, while 88% of the 12 500 quads the detector tried there
/// that were no tag stopped here.
const COARSE_LEAD: f64 = 0.6;

/// Ids scored at every blur after the first round: the true id of a
/// readable tag ranks far above the 16th at any blur of the range, while
/// every id more costs seven dot products of a grid.
const FINE_IDS: usize = 16;

/// Cells the blur model looks at on each side (a Gaussian of 1.3 cells
/// puts about 1% of its weight beyond 3.5 cells).
const REACH: i64 = 3;

/// Most codewords a family may have for a likelihood reading (ids times 4
/// rotations): the reading compares every one of them, which for ct14's
/// 1024 costs about a tenth of a millisecond; ct8's 262 144 are out of
/// reach and keep the hard reading only.
const MAX_CODEWORDS: usize = 4096;

/// The best codeword's fit must beat the best fit of any other id by this
/// factor (ratio of trimmed mean squared residuals). Measured with the
/// tags' true corners and on the 35 000 quads the detector decoded on the
/// wild set: at a ratio of 4, 1 of about 25 000 quads that were no tag
/// read as one; at 5, none, and no tag read as a wrong id.
const MIN_RATIO: f64 = 5.0;

/// Share of the informative cells a codeword's fit is scored on, the best
/// fitting ones: 15% of the cells may be hidden or lit by glare.
const TRIM_KEEP: f64 = 0.85;

/// Ids whose best codeword is scored with the trimmed fit: the best ones
/// by the plain fit (an id further down cannot overtake them by dropping
/// its worst cells when the true codeword is among them).
const TRIMMED_IDS: usize = 8;

/// Fitted contrast of the best codeword, as a fraction of the tag's
/// measured black-to-white contrast (the cells are normalised by it).
/// Below 0.3 the grid is nearly flat: clutter, not cells. Above 3.0 the
/// frame and margin levels the samples were normalised by may not be the
/// tag's. On the wild set the right readings lay between 0.7 and 3.4, the
/// quads that were no tag but fitted a codeword at 0.03 to 0.2.
///
/// Past the upper bound the reading is faint ([`FAINT_SCALE_MAX`]).
const SCALE_RANGE: (f64, f64) = (0.3, 3.0);

/// Largest fitted contrast of a faint reading ([`LikelyFit::faint`]): one
/// past [`SCALE_RANGE`], whose cells show several times the contrast the
/// tag's frame and margin do. Blur drags the one-cell margin towards the
/// frame, so on a tag blurred by more than about a cell the ring levels
/// the cells are normalised by nearly meet (with the tags' true corners
/// on the wild set, right readings reached 14), but so does an occluder
/// or glare over the frame, which may also have moved the quad: read on
/// the detector's quads, 13 of the wild set's faint readings had a corner
/// 3-7 px off. A faint reading therefore stands in the detector only on
/// the corners of the print aligned to the image
/// (`detect::decoding::unless_faint`), and comes after every other
/// reading of its quad. So, up to 8 read 142 more of the wild set's 6001
/// markers (2 lost), none rough, and none of the tag-free frames; the
/// few right readings past it are not worth a wider door for clutter.
const FAINT_SCALE_MAX: f64 = 8.0;

/// Every codeword of a family, with what the fit needs of each as the blur
/// shows it. The dot products of the samples with all codewords are not
/// taken cell by cell: the samples are blurred instead of the codewords
/// (the blur is symmetric, so `<y, B x> = <B y, x>`), and the informative
/// cells are split into groups of 8 whose sums for every 8-bit black/white
/// pattern are tabled once per blur and rotation, so that each codeword
/// costs one table look-up per group (about 12 000 additions per blur and
/// rotation for ct14, against 184 000 products cell by cell).
pub(crate) struct Codebook {
    /// Grid side (cells).
    n: usize,
    /// Ids, in codeword order.
    ids: Vec<u64>,
    /// Informative cells (not under the centre checker); the same set at
    /// every rotation.
    informative: Vec<usize>,
    /// Cells under the centre checker (half black, half white disc).
    covered: Vec<usize>,
    /// Upright cells of each group of 8 (`usize::MAX` pads the last).
    groups: Vec<[usize; GROUP]>,
    /// Black cells of each id in each group, as 8-bit patterns
    /// (`ids.len() * groups.len()`).
    patterns: Vec<u8>,
    /// The same for each id's seen grid at each rotation (rotation-major,
    /// then id, then group), over the upright groups: one table of group
    /// sums then serves all four rotations ([`Codebook::each_dot`]).
    turned: Vec<u8>,
    /// Per blur: axis weights of the offsets `-REACH..=REACH`.
    weights: Vec<Vec<f64>>,
    /// Per blur: what the white margin and black frame around the grid add
    /// to each cell's sample.
    outside: Vec<Vec<f64>>,
    /// Per blur, rotation and id: sum and sum of squares of the template
    /// over the informative cells.
    sums: Vec<(f64, f64)>,
    /// Per rotation and id: the seen grid's black cells as a bit set of
    /// [`Codebook::bit_words`] words (cell `c` is bit `c % 64` of word
    /// `c / 64`), for [`crate::nearest`]'s cell-by-cell distances.
    black_bits: Vec<u64>,
    /// The shading basis ([`crate::shaded`]) orthonormal over the
    /// informative cells, one `informative`-long vector per term.
    shade_basis: Vec<Vec<f64>>,
    /// Per rotation and id, at the middle blur ([`COARSE_SIGMA`]): the
    /// template's dot product with each vector of the shading basis
    /// ([`crate::shaded::TERMS`] of them), then its squared norm over the
    /// informative cells once the basis is projected out.
    shade_coarse: Vec<f64>,
}

/// Cells per look-up group: one byte of pattern.
const GROUP: usize = 8;

/// Codewords whose first-round dot products [`Codebook::each_dot`] sums
/// side by side: one sum is a chain of dependent additions (23 groups for
/// ct14), each waiting on the last; eight chains at once keep the adder
/// busy. On 600 wild frames (`coppertag detect`, perf) the first round's
/// share of the samples went from 4.9% to 4.0%, and the decode stage took
/// 0.988 of its time, with the same detections.
const DOT_LANES: usize = 8;

/// The pattern of group `g` (bit `b` for its cell `g[b]`; `usize::MAX`
/// pads) whose cells `black` says are black.
fn group_pattern(g: &[usize; GROUP], black: impl Fn(usize) -> bool) -> u8 {
    g.iter()
        .enumerate()
        .filter(|&(_, &c)| c != usize::MAX && black(c))
        .fold(0u8, |acc, (b, _)| acc | (1 << b))
}

impl std::fmt::Debug for Codebook {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Codebook")
            .field("ids", &self.ids.len())
            .field("cells", &self.informative.len())
            .field("blurs", &SIGMAS.len())
            .finish()
    }
}

impl Codebook {
    /// The codebook of `family`, or `None` when it has too many codewords
    /// ([`MAX_CODEWORDS`]) or a centre checker that is not the same at
    /// every rotation.
    pub(crate) fn new(family: &Family) -> Option<Self> {
        let ids = family
            .max_id()
            .checked_sub(family.min_id())?
            .checked_add(1)?;
        if ids.saturating_mul(4) > MAX_CODEWORDS as u64 {
            return None;
        }
        let n = family.grid();
        let informative: Vec<usize> = (0..n * n).filter(|&c| !family.is_covered(c)).collect();
        let covered: Vec<usize> = (0..n * n).filter(|&c| family.is_covered(c)).collect();
        if (0..4).any(|d| {
            covered
                .iter()
                .any(|&c| !family.is_covered(rotate_cell(c, n, d)))
        }) {
            return None;
        }
        let groups: Vec<[usize; GROUP]> = informative
            .chunks(GROUP)
            .map(|g| std::array::from_fn(|b| g.get(b).copied().unwrap_or(usize::MAX)))
            .collect();
        let ids: Vec<u64> = (family.min_id()..=family.max_id()).collect();
        let mut patterns = Vec::with_capacity(ids.len() * groups.len());
        for &id in &ids {
            let black = encode_cells(family, id).ok()?;
            patterns.extend(groups.iter().map(|g| group_pattern(g, |c| black[c])));
        }
        let weights: Vec<Vec<f64>> = SIGMAS.iter().map(|&s| cell_weights(s, REACH)).collect();
        let zero = vec![0.0; n * n];
        let outside: Vec<Vec<f64>> = SIGMAS
            .iter()
            .map(|&s| blur_grid(&zero, n, s, REACH))
            .collect();
        let mut book = Self {
            n,
            ids,
            informative,
            covered,
            groups,
            patterns,
            turned: Vec::new(),
            weights,
            outside,
            sums: Vec::new(),
            black_bits: Vec::new(),
            shade_basis: Vec::new(),
            shade_coarse: Vec::new(),
        };
        let all = vec![true; book.informative.len()];
        book.shade_basis = crate::shaded::basis(n, &book.informative, &all);
        // Indexed blur-major, then rotation, then id; each seen grid is
        // made once for all blurs.
        let per_blur = 4 * book.ids.len();
        let mut sums = vec![(0.0, 0.0); SIGMAS.len() * per_blur];
        let stride = crate::shaded::TERMS + 1;
        let mut shade_coarse = vec![0.0; 4 * book.ids.len() * stride];
        for d in 0..4 {
            for i in 0..book.ids.len() {
                let seen = book.seen(i, d);
                for s in 0..SIGMAS.len() {
                    let (mut sum, mut sq) = (0.0, 0.0);
                    let t = book.template_of(&seen, s);
                    for &v in &t {
                        sum += v;
                        sq += v * v;
                    }
                    sums[s * per_blur + d * book.ids.len() + i] = (sum, sq);
                    if s == COARSE_SIGMA {
                        let at = (d * book.ids.len() + i) * stride;
                        let mut along = 0.0;
                        for (k, q) in book.shade_basis.iter().enumerate() {
                            let a: f64 = q.iter().zip(&t).map(|(x, y)| x * y).sum();
                            shade_coarse[at + k] = a;
                            along += a * a;
                        }
                        shade_coarse[at + crate::shaded::TERMS] = sq - along;
                    }
                }
            }
        }
        book.sums = sums;
        book.shade_coarse = shade_coarse;
        // Each seen grid's black cells, as a bit set and as the patterns of
        // the upright groups.
        let words = book.bit_words();
        let mut black_bits = vec![0u64; 4 * book.ids.len() * words];
        let mut turned = Vec::with_capacity(4 * book.ids.len() * book.groups.len());
        for d in 0..4 {
            for i in 0..book.ids.len() {
                let seen = book.seen(i, d);
                let at = (d * book.ids.len() + i) * words;
                for (c, &v) in seen.iter().enumerate() {
                    if v == 0.0 {
                        black_bits[at + c / 64] |= 1 << (c % 64);
                    }
                }
                turned.extend(
                    book.groups
                        .iter()
                        .map(|g| group_pattern(g, |c| seen[c] == 0.0)),
                );
            }
        }
        book.black_bits = black_bits;
        book.turned = turned;
        Some(book)
    }

    /// Grid side (cells).
    pub(crate) fn grid(&self) -> usize {
        self.n
    }

    /// Number of ids (codewords per rotation).
    pub(crate) fn ids(&self) -> usize {
        self.ids.len()
    }

    /// The id of the codeword index `i`.
    pub(crate) fn id(&self, i: usize) -> u64 {
        self.ids[i]
    }

    /// Informative cells (not under the centre checker), row-major.
    pub(crate) fn informative(&self) -> &[usize] {
        &self.informative
    }

    /// Words of 64 bits a grid's bit set takes.
    pub(crate) fn bit_words(&self) -> usize {
        (self.n * self.n).div_ceil(64)
    }

    /// Black cells of codeword `i` seen at `d` quarter turns, as a bit set
    /// ([`Codebook::bit_words`] words).
    pub(crate) fn black_bits(&self, i: usize, d: usize) -> &[u64] {
        let words = self.bit_words();
        let at = (d * self.ids.len() + i) * words;
        &self.black_bits[at..at + words]
    }

    /// The seen grid of codeword `i` at `d` quarter turns (0 black, 1
    /// white, 0.5 under the centre checker).
    pub(crate) fn seen_grid(&self, i: usize, d: usize) -> Vec<f64> {
        self.seen(i, d)
    }

    /// The best plain fit of every id (score, rotation; an infinite score
    /// for none), from `z`, the samples blurred inside the grid by a blur
    /// whose templates' sums are close to those of blur `s` of
    /// [`SIGMAS`], and `outside`, the samples' dot product with what the
    /// margin and frame add through that blur: the codebook's first round,
    /// one table look-up per group of 8 cells and codeword
    /// ([`Codebook::each_dot`]). The dot products are left in `dots`
    /// (rotation-major, then id), for a reading that takes the same
    /// samples further ([`crate::shaded`]).
    pub(crate) fn score_all(
        &self,
        z: &[f64],
        outside: f64,
        y_sums: (f64, f64),
        s: usize,
        dots: &mut Vec<f64>,
    ) -> Vec<(f64, usize)> {
        let k = self.informative.len() as f64;
        let nids = self.ids.len();
        let mut best = vec![(f64::INFINITY, 0usize); nids];
        dots.clear();
        self.each_dot(z, outside, |d, i, dot| {
            dots.push(dot);
            let sums = self.sums[(s * 4 + d) * nids + i];
            if let Some((_, _, score)) = plain_fit(dot, sums, y_sums, k) {
                if score < best[i].0 {
                    best[i] = (score, d);
                }
            }
        });
        best
    }

    /// `<y, t>` over the informative cells for every codeword's template
    /// at blur `s`, from `z`, the samples blurred inside the grid by blur
    /// `s`, and `outside`, their dot product with what the margin and
    /// frame add through it: `f(d, i, dot)` for each rotation `d` and id
    /// index `i`, one table look-up per group of 8 cells and codeword.
    fn each_dot(&self, z: &[f64], outside: f64, mut f: impl FnMut(usize, usize, f64)) {
        let z_inf: f64 = self.informative.iter().map(|&c| z[c]).sum();
        let z_cov: f64 = 0.5 * self.covered.iter().map(|&c| z[c]).sum::<f64>();
        let ng = self.groups.len();
        // Sum of z over the black cells of every pattern of each group,
        // once: the seen grids' patterns (`turned`) are over the upright
        // groups at every rotation. One 256-entry table per group, so that
        // a pattern byte indexes it with no bounds check.
        let mut tables = vec![[0.0f64; 256]; ng];
        for (cells, t) in self.groups.iter().zip(&mut tables) {
            let zg: [f64; GROUP] = std::array::from_fn(|b| match cells[b] {
                usize::MAX => 0.0,
                c => z[c],
            });
            for v in 1..256usize {
                t[v] = t[v & (v - 1)] + zg[v.trailing_zeros() as usize];
            }
        }
        let nids = self.ids.len();
        // Each codeword's sum runs over its groups in order, as one chain
        // of additions: [`DOT_LANES`] codewords are summed side by side, so
        // that their chains overlap instead of each waiting on the last
        // addition's latency. Each sum keeps its own order, so the dot
        // products are the same to the bit.
        let mut k = 0;
        for block in self.turned.chunks(ng * DOT_LANES) {
            let lanes = block.len() / ng;
            let mut black = [0.0f64; DOT_LANES];
            for (g, t) in tables.iter().enumerate() {
                for (l, b) in black.iter_mut().enumerate().take(lanes) {
                    *b += t[usize::from(block[l * ng + g])];
                }
            }
            for b in &black[..lanes] {
                f(k / nids, k % nids, z_inf - b + z_cov + outside);
                k += 1;
            }
        }
    }

    /// The shading basis over the informative cells (see `shade_basis`).
    pub(crate) fn shade_basis(&self) -> &[Vec<f64>] {
        &self.shade_basis
    }

    /// Codeword `i` at `d` quarter turns at the middle blur
    /// ([`COARSE_SIGMA`]): its template's dot products with the shading
    /// basis, and its squared norm with the basis projected out.
    pub(crate) fn shade_coarse(&self, d: usize, i: usize) -> (&[f64], f64) {
        let stride = crate::shaded::TERMS + 1;
        let at = (d * self.ids.len() + i) * stride;
        let v = &self.shade_coarse[at..at + stride];
        (&v[..self.shade_basis.len()], v[crate::shaded::TERMS])
    }

    /// `<y, t>` over the informative cells for every codeword's template
    /// at the middle blur ([`COARSE_SIGMA`]), rotation-major, then id: the
    /// first round's dot products ([`Codebook::score_all`]).
    pub(crate) fn coarse_dots(&self, y: &[f64]) -> Vec<f64> {
        let (z, outside) = self.blurred_samples(y, COARSE_SIGMA);
        let mut dots = Vec::with_capacity(4 * self.ids.len());
        self.each_dot(&z, outside, |_, _, dot| dots.push(dot));
        dots
    }

    /// `y` (n x n) with its cells off the informative set zeroed, blurred
    /// inside the grid by blur `s`, and its dot product with what the
    /// margin and frame add through that blur.
    fn blurred_samples(&self, y: &[f64], s: usize) -> (Vec<f64>, f64) {
        let mut masked = vec![0.0; self.n * self.n];
        for &c in &self.informative {
            masked[c] = y[c];
        }
        let z = self.blur_inside(&masked, s);
        let outside = self
            .informative
            .iter()
            .map(|&c| y[c] * self.outside[s][c])
            .sum();
        (z, outside)
    }

    /// A fit of codeword `i` at `d` quarter turns and blur `s` with the
    /// lead `ratio` and fitted contrast `scale`.
    pub(crate) fn fit_of(&self, i: usize, d: usize, s: usize, ratio: f64, scale: f64) -> LikelyFit {
        LikelyFit {
            id: self.ids[i],
            rotation: d,
            index: i,
            blur: s,
            ratio,
            scale,
        }
    }

    /// The fit of a smeared reading ([`crate::motion`]) of codeword `i` at
    /// `d` quarter turns with the lead `ratio` and fitted contrast `scale`.
    pub(crate) fn smeared_fit(&self, i: usize, d: usize, ratio: f64, scale: f64) -> LikelyFit {
        LikelyFit {
            id: self.ids[i],
            rotation: d,
            index: i,
            blur: SMEAR_BLUR,
            ratio,
            scale,
        }
    }

    /// The seen grid of codeword `i` at `d` quarter turns (0 black, 1
    /// white, 0.5 under the centre checker).
    fn seen(&self, i: usize, d: usize) -> Vec<f64> {
        let n = self.n;
        let mut seen = vec![0.5; n * n];
        let ng = self.groups.len();
        for (g, cells) in self.groups.iter().enumerate() {
            let p = self.patterns[i * ng + g];
            for (b, &c) in cells.iter().enumerate() {
                if c != usize::MAX {
                    seen[rotate_cell(c, n, d)] = if p >> b & 1 == 1 { 0.0 } else { 1.0 };
                }
            }
        }
        seen
    }

    /// The template of codeword `i` at `d` quarter turns and blur `s`, on
    /// the informative cells.
    pub(crate) fn template(&self, i: usize, d: usize, s: usize) -> Vec<f64> {
        self.template_of(&self.seen(i, d), s)
    }

    /// [`Codebook::template`] of the seen grid `seen`.
    fn template_of(&self, seen: &[f64], s: usize) -> Vec<f64> {
        let t = self.blur_inside(seen, s);
        self.informative
            .iter()
            .map(|&c| t[c] + self.outside[s][c])
            .collect()
    }

    /// How well a grid of cell samples (row-major, any grey scale: the fit
    /// takes out contrast and offset) fits the codeword of `fit`: the
    /// returned function gives its trimmed score, less is better, or
    /// `None` for a flat or inverted fit. For aligning a quad to a
    /// codeword.
    pub(crate) fn scorer(&self, fit: &LikelyFit) -> impl FnMut(&[f64]) -> Option<f64> + '_ {
        let t = self.template(fit.index, fit.rotation, fit.blur);
        let mut ys = Vec::with_capacity(t.len());
        move |cells: &[f64]| {
            ys.clear();
            ys.extend(self.informative.iter().map(|&c| cells[c]));
            trimmed(&t, &ys).map(|(score, _)| score)
        }
    }

    /// `y` blurred by blur `k` within the grid (nothing outside it): the
    /// rows, then the columns.
    fn blur_inside(&self, y: &[f64], k: usize) -> Vec<f64> {
        let rows = blur_axis(y, self.n, &self.weights[k], false);
        blur_axis(&rows, self.n, &self.weights[k], true)
    }
}

/// [`LikelyFit::blur`] of a smeared reading ([`crate::motion`]): no
/// round template; such a fit is never aligned ([`LikelyFit::promising`]).
const SMEAR_BLUR: usize = usize::MAX;

/// The best codeword for a grid, and how clearly it wins.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LikelyFit {
    /// Decoded id.
    pub id: u64,
    /// Quarter turns, as in [`crate::grid_code::GridReading::rotation`].
    pub rotation: usize,
    /// Index of the codeword's id in the book.
    index: usize,
    /// Index of its blur in [`SIGMAS`].
    blur: usize,
    /// Trimmed score of the best id's fit over the second id's (less is
    /// clearer).
    ratio: f64,
    /// Fitted contrast, in units of the tag's measured contrast.
    scale: f64,
}

impl LikelyFit {
    /// Whether the fit reads the grid: one id clearly best
    /// ([`MIN_RATIO`]) with a plausible contrast ([`SCALE_RANGE`], or up
    /// to [`FAINT_SCALE_MAX`] for a [faint](LikelyFit::faint) reading).
    pub(crate) fn reads(&self) -> bool {
        self.ratio * MIN_RATIO < 1.0 && self.plausible()
    }

    /// Whether the best id is worth aligning the quad to: a plausible
    /// contrast, not a faint one, and a lead of at least
    /// [`PROMISING_RATIO`]. (Aligning quads to faint fits too read 46 more
    /// of the wild set's markers and lost as many others, for the cost of
    /// the alignments.)
    pub(crate) fn promising(&self) -> bool {
        self.blur != SMEAR_BLUR
            && self.ratio * PROMISING_RATIO < 1.0
            && self.plausible()
            && !self.faint()
    }

    /// Whether the fitted contrast is past [`SCALE_RANGE`] (see
    /// [`FAINT_SCALE_MAX`]).
    pub(crate) fn faint(&self) -> bool {
        self.scale > SCALE_RANGE.1
    }

    fn plausible(&self) -> bool {
        (SCALE_RANGE.0..=FAINT_SCALE_MAX).contains(&self.scale)
    }
}

/// The best id's trimmed fit must beat the second id's by this factor for
/// the quad to be aligned to it ([`Codebook::scorer`]): on the 35 000 quads
/// the detector decoded on the wild set, 1 in 300 of those that were no
/// tag came within a factor 2 and a tenth of the tags' quads fell short of
/// [`MIN_RATIO`] there, mostly for corners a pixel or two off.
const PROMISING_RATIO: f64 = 2.0;

/// `src` (an `n` x `n` grid, row-major) blurred along one axis (down the
/// columns when `vertical`) by the weights `w` of the offsets
/// `-REACH..=REACH`, cells beyond the grid counting as nothing.
///
/// Each cell's sum takes its terms offset by offset, in order, skipping
/// those beyond the grid: one offset at a time over whole runs of cells,
/// slice by slice, which the compiler vectorises, where a loop over the
/// offsets inside each cell's sum tested every term. The sums and their
/// order are the same (this loop builds the codebook's 7168 templates,
/// most of the first frame's time).
fn blur_axis(src: &[f64], n: usize, w: &[f64], vertical: bool) -> Vec<f64> {
    let mut out = vec![0.0; n * n];
    for (o, &wo) in w.iter().enumerate() {
        // Cell k takes the term of cell k + o - REACH when that is inside:
        // the cells from `skip` on take those from `lead` on, `len` of
        // them (one of `skip` and `lead` is 0).
        let reach = REACH as usize;
        let (skip, lead) = (reach.saturating_sub(o), o.saturating_sub(reach));
        let len = n.saturating_sub(skip.max(lead));
        if len == 0 {
            continue;
        }
        if vertical {
            for k in skip..skip + len {
                let row = &src[(k - skip + lead) * n..][..n];
                for (d, &v) in out[k * n..][..n].iter_mut().zip(row) {
                    *d += wo * v;
                }
            }
        } else {
            for m in 0..n {
                let row = &src[m * n + lead..][..len];
                for (d, &v) in out[m * n + skip..][..len].iter_mut().zip(row) {
                    *d += wo * v;
                }
            }
        }
    }
    out
}

/// The least-squares fit `y = a t + c` over `k` cells from the dot product
/// of `t` and `y` and their sums and sums of squares: `(a, c, score)` with
/// the score the mean squared residual divided by `a^2` (the noise relative
/// to the contrast the codeword explains); `None` for a flat or inverted
/// fit.
pub(crate) fn plain_fit(
    dot: f64,
    t_sums: (f64, f64),
    y_sums: (f64, f64),
    k: f64,
) -> Option<(f64, f64, f64)> {
    let (st, stt) = t_sums;
    let (sy, syy) = y_sums;
    let var = stt - st * st / k;
    let cov = dot - st * sy / k;
    if var <= 1e-9 || cov <= 0.0 {
        return None;
    }
    let a = cov / var;
    let c = (sy - a * st) / k;
    let resid = (syy - sy * sy / k - cov * cov / var).max(0.0) / k;
    Some((a, c, resid / (a * a)))
}

/// Trimmed score of the template `t` (informative cells) against `y`:
/// fitted by least squares, then the mean of the smallest [`TRIM_KEEP`]
/// share of squared residuals divided by `a^2`, and `a`.
pub(crate) fn trimmed(t: &[f64], y: &[f64]) -> Option<(f64, f64)> {
    let k = t.len() as f64;
    let dot = t.iter().zip(y).map(|(a, b)| a * b).sum();
    let ts = (t.iter().sum(), t.iter().map(|v| v * v).sum());
    let ys = (y.iter().sum(), y.iter().map(|v| v * v).sum());
    let (a, c, _) = plain_fit(dot, ts, ys, k)?;
    let mut r: Vec<f64> = t
        .iter()
        .zip(y)
        .map(|(tv, yv)| (yv - a * tv - c).powi(2))
        .collect();
    let keep = ((r.len() as f64 * TRIM_KEEP) as usize).max(1);
    r.select_nth_unstable_by(keep - 1, f64::total_cmp);
    Some((r[..keep].iter().sum::<f64>() / keep as f64 / (a * a), a))
}

/// The ids of a first round's scores `coarse` (per id: score, less is
/// better, and rotation) best first, at most `keep` of them; `None` when
/// the best does not lead the second by `lead` (its score over the
/// second's at most `lead`): most quads that are no tag fit many ids
/// about equally.
pub(crate) fn leading(coarse: &[(f64, usize)], lead: f64, keep: usize) -> Option<Vec<usize>> {
    let mut order: Vec<usize> = (0..coarse.len())
        .filter(|&i| coarse[i].0.is_finite())
        .collect();
    order.sort_by(|&a, &b| coarse[a].0.total_cmp(&coarse[b].0));
    if let [a, b, ..] = order[..] {
        if coarse[a].0 > lead * coarse[b].0 {
            return None;
        }
    }
    order.truncate(keep);
    Some(order)
}

/// The best codeword of `book` for the cells' whiteness `y` (the seen `n`
/// x `n` grid, row-major, 0 at the frame's black, 1 at the margin's
/// white), and how clearly it wins ([`LikelyFit::reads`]); `None` when no
/// codeword fits at all.
///
/// Three rounds, each on fewer codewords with a finer score: every
/// codeword at one middle blur ([`COARSE_SIGMA`]) by table look-ups; the
/// [`FINE_IDS`] best ids at their best rotation at every blur by dot
/// products with the blurred samples; the [`TRIMMED_IDS`] best of those on
/// their best-fitting cells.
pub(crate) fn read_likely(book: &Codebook, y: &[f64]) -> Option<LikelyFit> {
    read_likely_keeping(book, y, &mut Vec::new())
}

/// [`read_likely`], leaving the first round's dot products in `dots`
/// ([`Codebook::coarse_dots`]; empty when no round ran).
pub(crate) fn read_likely_keeping(
    book: &Codebook,
    y: &[f64],
    dots: &mut Vec<f64>,
) -> Option<LikelyFit> {
    dots.clear();
    let n = book.n;
    if y.len() != n * n {
        return None;
    }
    let k = book.informative.len() as f64;
    let ys: Vec<f64> = book.informative.iter().map(|&c| y[c]).collect();
    let y_sums = (ys.iter().sum(), ys.iter().map(|v| v * v).sum());
    let nids = book.ids.len();
    // `<y, t>` over the informative cells for the template of the seen grid
    // `x` at blur `s`, from the blurred samples `z`: the blur is symmetric,
    // so `<y, B x + outside> = <B y, x> + <y, outside>`.
    let blur_at = |s: usize| book.blurred_samples(y, s);

    // Round 1: every codeword at the middle blur (the other blurs are
    // computed only for a grid that passes it).
    let coarse_blur = blur_at(COARSE_SIGMA);
    let (z, outside) = &coarse_blur;
    let coarse = book.score_all(z, *outside, y_sums, COARSE_SIGMA, dots);
    let order = leading(&coarse, COARSE_LEAD, FINE_IDS)?;
    let blurred: Vec<(Vec<f64>, f64)> = (0..SIGMAS.len())
        .map(|s| {
            if s == COARSE_SIGMA {
                coarse_blur.clone()
            } else {
                blur_at(s)
            }
        })
        .collect();

    // Round 2: those ids at every blur: (score, id index, blur).
    let mut fine: Vec<(f64, usize, usize)> = order
        .iter()
        .filter_map(|&i| {
            let d = coarse[i].1;
            let x = book.seen(i, d);
            (0..SIGMAS.len())
                .filter_map(|s| {
                    let (z, outside) = &blurred[s];
                    let dot = x.iter().zip(z).map(|(a, b)| a * b).sum::<f64>() + outside;
                    let sums = book.sums[(s * 4 + d) * nids + i];
                    plain_fit(dot, sums, y_sums, k).map(|(_, _, score)| (score, i, s))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))
        })
        .collect();
    fine.sort_by(|a, b| a.0.total_cmp(&b.0));
    fine.truncate(TRIMMED_IDS);

    // Round 3: the best of those on their best-fitting cells.
    let mut scored: Vec<(f64, usize, usize, f64)> = fine
        .iter()
        .filter_map(|&(_, i, s)| {
            let t = book.template(i, coarse[i].1, s);
            let (score, a) = trimmed(&t, &ys)?;
            Some((score, i, s, a))
        })
        .collect();
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    let &(r1, i, s, a) = scored.first()?;
    let r2 = scored.get(1).map_or(f64::INFINITY, |s| s.0);
    Some(LikelyFit {
        id: book.ids[i],
        rotation: coarse[i].1,
        index: i,
        blur: s,
        ratio: r1 / r2,
        scale: a,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`blur_axis`] gives, bit for bit, each cell's sum of its terms in
    /// order of offset, skipping those beyond the grid: the definition the
    /// codebook's sums were first computed with.
    #[test]
    fn blur_axis_sums_each_cell_in_order() {
        let naive = |src: &[f64], n: usize, w: &[f64], vertical: bool| {
            let mut out = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    let mut s = 0.0;
                    for (o, wo) in w.iter().enumerate() {
                        let t = o as i64 - REACH;
                        let (a, b) = if vertical {
                            (i as i64 + t, j as i64)
                        } else {
                            (i as i64, j as i64 + t)
                        };
                        if (0..n as i64).contains(&a) && (0..n as i64).contains(&b) {
                            s += wo * src[a as usize * n + b as usize];
                        }
                    }
                    out[i * n + j] = s;
                }
            }
            out
        };
        for n in [1, 2, 3, 5, 7, 14] {
            let src: Vec<f64> = (0..n * n)
                .map(|c| ((c * 7919) % 101) as f64 / 37.0)
                .collect();
            for &sigma in &SIGMAS {
                let w = cell_weights(sigma, REACH);
                for vertical in [false, true] {
                    let got = blur_axis(&src, n, &w, vertical);
                    let want = naive(&src, n, &w, vertical);
                    assert!(
                        got.iter()
                            .zip(&want)
                            .all(|(a, b)| a.to_bits() == b.to_bits()),
                        "n {n} sigma {sigma} vertical {vertical}"
                    );
                }
            }
        }
    }

    /// The seen whiteness of tag `id` at rotation `d`, blurred by `sigma`
    /// cells, with a contrast `a`, black level `c` and a deterministic
    /// noise of amplitude `noise`.
    fn seen(
        family: &Family,
        id: u64,
        d: usize,
        sigma: f64,
        a: f64,
        c: f64,
        noise: f64,
    ) -> Vec<f64> {
        let n = family.grid();
        let g = crate::grid_code::seen_whiteness(family, id, d);
        blur_grid(&g, n, sigma, REACH)
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let h = ((i as f64 + 1.0) * 12.9898).sin() * 43_758.545;
                c + a * v + noise * (h - h.floor() - 0.5)
            })
            .collect()
    }

    #[test]
    fn a_tag_too_blurred_for_the_hard_reading_is_read_by_likelihood() {
        let fam = Family::ct14();
        let book = Codebook::new(fam).unwrap();
        for (id, d) in [(7, 0), (131, 1), (255, 3)] {
            let y = seen(fam, id, d, 1.0, 0.4, 0.3, 0.05);
            let bits: Vec<bool> = y.iter().map(|&v| v < 0.5).collect();
            assert!(
                crate::grid_code::decode_cells(fam, &bits, &[]).is_none(),
                "the blur must defeat the hard reading for this test to mean anything"
            );
            let r = read_likely(&book, &y).expect("a fit");
            assert!(r.reads(), "{r:?}");
            assert_eq!((r.id, r.rotation), (id, d));
        }
    }

    /// Cells showing several times the contrast the grid is normalised by
    /// (a tag blurred past a cell, whose margin and frame meet) read as a
    /// faint reading up to [`FAINT_SCALE_MAX`], and not past it.
    #[test]
    fn a_tag_brighter_than_its_frame_reads_faint() {
        let fam = Family::ct14();
        let book = Codebook::new(fam).unwrap();
        for (id, d, a, faint) in [(7, 0, 0.8, false), (131, 1, 5.0, true), (200, 2, 7.5, true)] {
            let y = seen(fam, id, d, 0.9, a, 0.3 - a / 2.0, 0.05 * a);
            let r = read_likely(&book, &y).expect("a fit");
            assert!(r.reads(), "{r:?}");
            assert_eq!((r.id, r.rotation, r.faint()), (id, d, faint), "{r:?}");
        }
        let y = seen(fam, 99, 3, 0.9, 12.0, -5.7, 0.6);
        assert!(read_likely(&book, &y).is_none_or(|r| !r.reads()));
    }

    #[test]
    fn flat_and_random_grids_are_not_read() {
        let fam = Family::ct14();
        let book = Codebook::new(fam).unwrap();
        assert!(read_likely(&book, &vec![0.5; 196]).is_none_or(|r| !r.reads()));
        // Smooth random blobs: a clutter quad's grey interior.
        for seed in 0..50u64 {
            let y: Vec<f64> = (0..196)
                .map(|i| {
                    let (r, c) = ((i / 14) as f64, (i % 14) as f64);
                    let s = seed as f64;
                    0.5 + 0.4 * ((r * 0.7 + s).sin() * (c * 0.5 + 2.0 * s).cos())
                })
                .collect();
            assert!(
                read_likely(&book, &y).is_none_or(|r| !r.reads()),
                "seed {seed}"
            );
        }
    }

    #[test]
    fn table_dot_products_are_the_templates_at_every_rotation() {
        // The first round's look-ups against `<y, B x> + <y, outside>`
        // computed cell by cell from each seen grid, for uneven samples
        // (no symmetry to hide a rotation mixed up).
        let book = Codebook::new(Family::ct14()).unwrap();
        let y: Vec<f64> = (0..196)
            .map(|i| ((i * 37 % 101) as f64 / 50.0 - 0.3) + 0.01 * i as f64)
            .collect();
        let dots = book.coarse_dots(&y);
        assert_eq!(dots.len(), 4 * book.ids());
        let (z, outside) = book.blurred_samples(&y, COARSE_SIGMA);
        for d in 0..4 {
            for i in 0..book.ids() {
                let x = book.seen(i, d);
                let want: f64 = x.iter().zip(&z).map(|(a, b)| a * b).sum::<f64>() + outside;
                let got = dots[d * book.ids() + i];
                assert!((got - want).abs() < 1e-9, "d {d} id {i}: {got} vs {want}");
            }
        }
    }

    /// The first round's sums, taken codeword by codeword as one chain of
    /// additions over the groups in order, each group's cells summed as
    /// its table entry sums them: what [`Codebook::each_dot`] must give to
    /// the bit, whatever it sums side by side.
    fn each_dot_one_by_one(book: &Codebook, z: &[f64], outside: f64) -> Vec<(usize, usize, f64)> {
        let z_inf: f64 = book.informative.iter().map(|&c| z[c]).sum();
        let z_cov: f64 = 0.5 * book.covered.iter().map(|&c| z[c]).sum::<f64>();
        let ng = book.groups.len();
        let nids = book.ids.len();
        book.turned
            .chunks_exact(ng)
            .enumerate()
            .map(|(k, pat)| {
                let black: f64 = pat
                    .iter()
                    .zip(&book.groups)
                    .map(|(&p, cells)| {
                        // A group's table entry adds its cells from the
                        // highest bit of the pattern down.
                        (0..GROUP)
                            .rev()
                            .filter(|&b| p & (1 << b) != 0 && cells[b] != usize::MAX)
                            .fold(0.0, |acc, b| acc + z[cells[b]])
                    })
                    .fold(0.0, |acc, v| acc + v);
                (k / nids, k % nids, z_inf - black + z_cov + outside)
            })
            .collect()
    }

    #[test]
    fn first_round_sums_side_by_side_are_the_sums_one_by_one_to_the_bit() {
        let mut book = Codebook::new(Family::ct14()).unwrap();
        let y: Vec<f64> = (0..196)
            .map(|i| ((i * 53 % 97) as f64 / 40.0 - 0.7) + 0.003 * i as f64)
            .collect();
        let (z, outside) = book.blurred_samples(&y, COARSE_SIGMA);
        let run = |book: &Codebook| {
            let mut got = Vec::new();
            book.each_dot(&z, outside, |d, i, dot| got.push((d, i, dot)));
            got
        };
        let want = each_dot_one_by_one(&book, &z, outside);
        assert_eq!(want.len(), 4 * book.ids());
        let got = run(&book);
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            assert_eq!((g.0, g.1, g.2.to_bits()), (w.0, w.1, w.2.to_bits()));
        }
        // A last block of fewer codewords than the lanes (ct14's 4096 fill
        // them all): three codewords fewer.
        let ng = book.groups.len();
        let keep = book.turned.len() - 3 * ng;
        book.turned.truncate(keep);
        let want = each_dot_one_by_one(&book, &z, outside);
        let got = run(&book);
        assert_eq!(got.len(), 4 * book.ids() - 3);
        for (g, w) in got.iter().zip(&want) {
            assert_eq!((g.0, g.1, g.2.to_bits()), (w.0, w.1, w.2.to_bits()));
        }
    }

    #[test]
    fn a_family_with_too_many_codewords_has_no_book() {
        assert!(Codebook::new(Family::ct8()).is_none());
        assert!(Codebook::new(Family::ct14()).is_some());
    }
}
