//! Stage 6: refinement and decoding of the candidate quads, best first, and
//! one detection per physical tag.
//!
//! A tag seen through an occluder usually has several candidate quads (a
//! triangle through a false corner on the occluder's edge, a same-side
//! recovery, ...) and a wrong one can still decode, the Reed-Solomon code
//! absorbing the misplaced cells. So a found tag that needed corrections
//! keeps up to [`DecodingParams::max_rivals`] more overlapping candidates
//! decoded, and the reading with the fewest corrections wins: the right
//! geometry explains the visible cells best.

use rayon::prelude::*;

use super::config::FamilySetting;
use super::outline::data_square_within;
use super::parallel::Workers;
use super::pitch::{rules_out, shown_grid};
use super::print_align;
use super::quads::Candidate;
use super::refine::{refine_candidate, RefineParams, RefineScratch, MARGIN_CELLS};
use super::reject::plainly_not_a_tag;
use super::rim;
use super::verify::{self, verify, Confirming, Verdict, Verified};
use super::Detection;
use crate::decode::{decode_quad_by, frame_misread_at_corners, Accept, DecodeParams, Promising};
use crate::family::Family;
use crate::geometry::CORNERS;
use crate::homography::Homography;
use crate::math::{centroid, inside, mean_side, norm, sub, to_full};
use crate::view::GrayView;

/// Default of [`DecodingParams::max_rivals`].
pub(crate) const MAX_RIVALS: usize = 6;

/// Smallest mean side of a rival candidate, as a share of the found tag's:
/// a rival reading wins only as a reading of the same tag, i.e. as a quad
/// of its data square, while a quad under a third of the tag's side lies
/// within its cells (a dark cell or block of cells, the centre checker),
/// which no placement of that data square explains. Such rivals are
/// counted as rivals that did not read, without being decoded: on the
/// paper's occlusion images three of a tag's eleven decoded quads were its
/// cells, at 0.15-0.3 ms each.
const RIVAL_MIN_SIDE: f64 = 1.0 / 3.0;

/// Parameters of stage 6, built once by [`crate::Detector::new`]; `fits`
/// is the frame's, set for each frame.
#[derive(Debug, Clone, Copy)]
pub(crate) struct DecodingParams<'f> {
    /// Most candidates refined and decoded per frame
    /// (`DetectorConfig::max_candidates`).
    pub max_attempts: usize,
    /// Most candidates in a row decoded to nothing before the loop gives
    /// up on the rest (a reading, or another family's square, starts the
    /// count again): `usize::MAX` (no such stop) but in the rim look
    /// (`RIM_MAX_FAILED_RUN` in `detect/mod.rs`).
    pub max_in_vain_run: usize,
    /// Extra overlapping candidates decoded for a tag already found with
    /// corrections.
    pub max_rivals: usize,
    /// Sub-pixel refinement.
    pub refine: RefineParams,
    /// Decoder thresholds.
    pub decode: DecodeParams,
    /// The model fits made so far in the frame ([`Fits`]), if kept.
    pub fits: Option<&'f Fits>,
    /// The built-in families not decoded, set for each frame: a quad
    /// that reads to nothing and reads plainly as one of them is that
    /// family's data square ([`reads_as_other_family`]).
    pub others: &'f [Target],
}

/// The model fits ([`verify`]) made in one frame, each with what it was
/// made of. Why: a reading judged when its quad is read (a reading by
/// the nearest codeword, the rim look's, the outline's) is fitted again,
/// unchanged, by the verify stage; on 600 wild frames 184 of 1558 fits
/// repeated one made before in the frame, 108 of their 792 ms. A fit is a
/// pure function of the image and its inputs, so taking it again from
/// here changes nothing, on any thread. Behind a lock: the fits are made
/// on the worker threads too; each holds it for a look-up or a push.
#[derive(Debug, Default)]
pub(crate) struct Fits(std::sync::Mutex<Vec<(FitKey, Verdict)>>);

/// What a fit of [`verify_reading`] is made of, bit for bit: the image
/// (its buffer and shape; a frame's fits are all made on the frame, whose
/// buffer stays as it is while it is detected), the reading's family, id,
/// corners, contrast, corrections and kind, and whether it is held. The
/// decoder's thresholds are the detector's, the same for every fit.
#[derive(Debug, PartialEq)]
struct FitKey {
    image: (usize, u32, u32, usize),
    family: String,
    id: u64,
    corners: [[u64; 2]; 4],
    contrast: u64,
    corrected: usize,
    kind: (bool, bool, bool, usize),
    held: bool,
}

impl Fits {
    /// The fit made of `key`, if one was.
    fn get(&self, key: &FitKey) -> Option<Verdict> {
        let fits = self
            .0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        fits.iter().find(|(k, _)| k == key).map(|(_, v)| v.clone())
    }

    /// Keeps the fit `v` made of `key`.
    fn put(&self, key: FitKey, v: Verdict) {
        let mut fits = self
            .0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        fits.push((key, v));
    }
}

/// A family decoded, with the corrections a reading of it may need.
#[derive(Debug, Clone)]
pub(crate) struct Target {
    /// The family.
    pub family: Family,
    /// Most Reed-Solomon symbol corrections accepted.
    pub max_corrected: usize,
}

impl Target {
    /// The target of a family setting: its family, at its limit.
    pub(crate) fn of(setting: &FamilySetting) -> Self {
        Self {
            family: setting.family.clone(),
            max_corrected: setting.correction_limit(),
        }
    }
}

/// A candidate's reading, and whether it was taken inside the candidate
/// as the printed tag's outline ([`super::outline`]) rather than of the
/// candidate's own quad.
#[derive(Debug, Clone)]
pub(crate) struct Reading {
    det: Detection,
    outline: bool,
}

impl Reading {
    /// Whether this reading of a tag is better than `other`: one of the
    /// data square's own quad over one inside an outline (its corners were
    /// seen, not inferred from the paper's edge), then [`better`].
    fn beats(&self, other: &Reading) -> bool {
        !self.outline && other.outline
            || (self.outline == other.outline && better(&self.det, &other.det))
    }
}

/// A tag found in this frame and how many rival candidates were tried.
#[derive(Debug, Clone)]
pub(crate) struct Found {
    reading: Reading,
    rivals: usize,
}

impl Found {
    /// The tag's reading.
    pub(crate) fn detection(&self) -> &Detection {
        &self.reading.det
    }

    /// Marks the tag as read in an upsampled small-tag region (see
    /// [`Detection::upsampled`]).
    pub(crate) fn mark_upsampled(&mut self) {
        self.reading.det.upsampled = true;
    }
}

/// Refines and decodes `candidates` (best first, working-image coordinates
/// scaled by `scale`) on the full-resolution `img`. Candidates whose centre
/// falls inside a tag already read cleanly are skipped, and so are those
/// [`plainly_not_a_tag`] refuses and those inside a square of a family
/// not decoded ([`Decoded::foreign`]). Returns the tags found, those
/// squares and the number of candidates decoded.
pub(crate) fn decode_candidates(
    img: &GrayView<'_>,
    candidates: &[Candidate],
    scale: f64,
    targets: &[Target],
    p: &DecodingParams,
    scratch: &mut RefineScratch,
) -> Decoded {
    decode_in_order(
        candidates,
        scale,
        p,
        |j, centre| outcome(img, &candidates[j], scale, centre, targets, p, scratch),
        |_, _, _| {},
    )
}

/// What decoding a candidate came to: refused by [`plainly_not_a_tag`]
/// before any reading, read (perhaps to nothing; boxed, as a reading is
/// large and most candidates read to nothing), or found to be the data
/// square of a built-in family that is not decoded (its refined corners:
/// see [`Decoded::foreign`]).
#[derive(Debug)]
pub(super) enum Outcome {
    Refused,
    Read(Option<Box<Reading>>),
    Foreign(Box<Quad>),
    /// Read to nothing that stands now, but to a reading that stands as
    /// a last resort ([`Decoded::last_resort`]).
    LastResort(Box<Reading>),
    /// Read, and to a last resort besides, kept in case verification
    /// drops the reading (the rim look's `unfitted_on_aligned`).
    ReadKeeping(Box<Reading>, Box<Reading>),
    /// Read to nothing, but the quad shows the print enough to be aligned
    /// to it later ([`Decoded::unread`]).
    Unread(Box<Unread>),
}

/// A quad's corners (full-resolution px).
pub(super) type Quad = [[f64; 2]; 4];

/// What the decoding loop came to ([`decode_candidates`]).
#[derive(Debug, Default)]
pub(crate) struct Decoded {
    /// The tags found.
    pub found: Vec<Found>,
    /// The data squares of tags of a built-in family that is not decoded
    /// (the cells' pitch shows that family's grid and no target's, see
    /// [`shown_grid`]), not inside a tag found: quads with four seen
    /// corners, and prints the rim look aligned; or quads that read by the
    /// code as such a family ([`reads_as_other_family`]). The candidates
    /// inside one are that tag's other quads (its outline, pieces of it),
    /// and a later look at its rim or around it could only find the same
    /// square again; skipping them took a third of the time of a ct14-only
    /// detector on the wild benchmark's 1080p frames, where the ct8 tags
    /// had cost as much as the ct14 ones. Why four seen corners: quads with
    /// estimated corners through clutter, 23 to 139 px, showed ct8's grid
    /// on 6 of the 3000 wild frames (phases 0.12-0.23), around ct14 tags, 4
    /// of which were then lost.
    pub foreign: Vec<Quad>,
    /// The candidates decoded.
    pub attempts: usize,
    /// Readings by the nearest codeword whose two or more hidden corners
    /// the model fit places surely ([`hidden_fitted`]), but which the
    /// quad itself cannot check ([`occluded_geometry_stands`]): taken
    /// only where no look found a tag ([`last_resorts`]), verified as
    /// every reading is ([`verify_one`] keeps them by the same rule,
    /// `hidden_corners_fitted`).
    ///
    /// Why last: under triangles, cables and bands over 30-40% of the
    /// square, such readings were right and dropped when read (kept as
    /// last resorts: on the wild set 24 more markers, every corner within
    /// 1.9 px of the truth; 7 on the calibration set, 1 on the ct8 twin).
    /// Taken as readings that stand, they also kept the rim look and the
    /// small-tag look from tags those read better: on the wild set 20
    /// corners went farther from the truth, 5 of them over 3 px. Taken
    /// last, no other detection changes.
    ///
    /// Shaded readings (`decode::QuadReading::shaded`) too, of quads and
    /// of the rim look: taken as readings that stand, they kept other
    /// quads of the same tags from readings with the corners 0.5-3 px
    /// closer (62 tags of the wild set) and, from the rim look, put
    /// estimated corners 3.1-3.4 px off on glared tags. As last resorts
    /// they found 132 more of the wild set's markers and 42 of the
    /// calibration set's, none rough, and no other detection moved a
    /// corner by more than 0.05 px for the worse.
    ///
    /// Readings under glare by the nearest codeword
    /// (`decode::QuadReading::glared`) of a candidate's own quad, judged
    /// here only ([`glare_standing`]): with every corner seen they
    /// found 16 more of the wild set's markers and 5 of the calibration
    /// set's, every corner within 1.6 px of the truth, and no other
    /// detection changed. Taken as readings that stand, 18 more, but 14
    /// other tags' corners moved, one to 2.6 px off; tried in the rim look
    /// too, with a corner allowed hidden, 104 more, 7 of them rough
    /// (corners under the glare 3.2-5.9 px off). Of the rim look's aligned
    /// print too, held to every corner seen like a quad's: 6 more of the
    /// wild set's markers and 3 of the calibration set's (29-44 px, every
    /// corner within 0.85 px of the truth), no other lost and the three
    /// others that moved no farther from the truth. With one hidden corner
    /// allowed there as a nearest-codeword reading's (within
    /// `HIDDEN_CORNER_TOL_PX` of the parallelogram), 13 more on the wild
    /// set, one of them rough (a hidden corner 3.15 px off at a sigma of
    /// 0.59 px); with hidden corners allowed only where the print's fixed
    /// look, aligned on its own, puts them too
    /// ([`GLARE_PRINT_AGREEMENT_PX`]), and such readings tried after the
    /// tag's others, 17 more, none rough.
    pub last_resort: Vec<Found>,
    /// Quads of candidates that read to nothing, outside every tag found
    /// when they were decoded, whose print's fixed look is strong
    /// ([`UNREAD_MIN_LOOK`]): [`aligned_unread`] aligns the print to those
    /// that lie in no tag found by any look.
    pub unread: Vec<Unread>,
}

/// A refined quad that read to nothing ([`Decoded::unread`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Unread {
    quad: Quad,
    /// Its candidate's estimated corners.
    estimated: [bool; 4],
    /// Its candidate's centroid.
    centre: [f64; 2],
    /// The print's fixed look of the quad as the data square.
    look: f64,
}

/// The [`Outcome`] of candidate `cand` (centroid `centre`): a pure
/// function of the image and the candidate.
pub(super) fn outcome(
    img: &GrayView<'_>,
    cand: &Candidate,
    scale: f64,
    centre: [f64; 2],
    targets: &[Target],
    p: &DecodingParams,
    scratch: &mut RefineScratch,
) -> Outcome {
    if plainly_not_a_tag(img, cand, scale, finest_grid(&p.refine)) {
        return Outcome::Refused;
    }
    attempt(img, cand, scale, centre, targets, p, scratch)
}

/// The reading of one candidate: its refined corners decoded.
fn attempt(
    img: &GrayView<'_>,
    cand: &Candidate,
    scale: f64,
    centre: [f64; 2],
    targets: &[Target],
    p: &DecodingParams,
    scratch: &mut RefineScratch,
) -> Outcome {
    if let Some(seen) = cand.rim {
        return rim_attempt(img, cand, &seen, scale, centre, targets, p, scratch);
    }
    let q = refine_candidate(img, cand, scale, &p.refine, scratch);
    // A quad of clutter reads to nothing, through every reading there is.
    let look = print_align::quad_look(img, &q);
    if look.no_print {
        return Outcome::Read(None);
    }
    let shown = shown_grid(img, &q);
    // A square showing another family's cells is that family's data
    // square, not a tag's outline around a blurred one either (the
    // outline's interior shows the cells at 0.8 of the square's scale,
    // off every family's period). Its candidate is that tag's when all
    // four corners were seen (see `Decoded::foreign`).
    if none_can_read(shown, targets) {
        return if cand.real == 4 {
            Outcome::Foreign(Box::new(q))
        } else {
            Outcome::Read(None)
        };
    }
    match quad_reading(img, cand, &q, shown, look.own, centre, targets, p) {
        Outcome::Read(None) | Outcome::Unread(_) if reads_as_other_family(img, &q, p) => {
            Outcome::Foreign(Box::new(q))
        }
        o => o,
    }
}

/// Whether quad `q` reads by the code alone
/// ([`crate::decode::read_by_code`]) as a built-in family the detector
/// does not decode (`p.others`), within the limit a detector of that
/// family accepts: then it is that family's data square
/// ([`Decoded::foreign`]), and the tag's other quads, its rim and a
/// small-tag look around it are passed over. Asked of refined quads that
/// read to nothing and of the rim look's aligned prints that show no
/// grid.
///
/// Why: a small tag of the other family (a data square of 20-30 px)
/// shows no pitch [`shown_grid`] can rule out, so every quad of it was
/// read through every reading there is, its rim and small-tag region
/// looked at, and its print aligned to its quads. On the benchmark's
/// cluttered 1080p frames a ct14-only detector spent a quarter of its
/// decoding time on the ct8 tags (8 of 21 ms on the worst frame). With
/// the limit less a margin of [`UNFIT_MARGIN`], the worst frame's time
/// fell less (22 against 19.6 ms), and the detections were the same
/// either way. The readings of the code alone cost little (a codebook
/// reading would score every codeword), and a tag of the family decoded
/// does not pass for one of the other: its cells would have to make a
/// codeword of the other family with its check symbol. On the wild set,
/// whose 6001 tags are all ct14, a ct14-only detector found the same tags
/// at the same corners and took about 2% more time (1500 frames, three
/// interleaved runs: 9.23 s against 9.40-9.49 s in all); gating the
/// reading by the quad's look of the print changed nothing measurable.
fn reads_as_other_family(img: &GrayView<'_>, q: &Quad, p: &DecodingParams) -> bool {
    p.others.iter().any(|t| {
        crate::decode::read_by_code(img, &t.family, q, &p.decode, t.max_corrected).is_some()
    })
}

/// The reading of candidate `cand`'s refined quad `q`, which shows the grid
/// `shown` ([`shown_grid`]): of the quad itself, else of the data square
/// within it, as the printed tag's outline; else the quad's reading that
/// stands as a last resort ([`Decoded::last_resort`]), if any; else,
/// where the print's fixed look of the quad (`look`) is strong enough, the
/// quad kept for [`aligned_unread`].
#[allow(clippy::too_many_arguments)]
fn quad_reading(
    img: &GrayView<'_>,
    cand: &Candidate,
    q: &Quad,
    shown: Option<usize>,
    look: Option<f64>,
    centre: [f64; 2],
    targets: &[Target],
    p: &DecodingParams,
) -> Outcome {
    // The quad's own reading, standing or as a last resort.
    let read_own = read(
        img,
        &cand.estimated,
        q,
        centre,
        targets,
        &p.decode,
        ReadAs {
            shown,
            promising: Promising::Align,
            glared: true,
            rim: false,
        },
    );
    let (own, last_resort) = match read_own.map(|d| (standing(img, &d, targets, p), d)) {
        Some((Standing::Stands, d)) => (unless_faint(img, d, targets, p), None),
        Some((Standing::LastResort | Standing::PrintConfirmed, d)) => (None, Some(d)),
        Some((Standing::Falls, _)) | None => (None, None),
    };
    let reading = own
        .map(|det| Reading {
            det,
            outline: false,
        })
        .or_else(|| {
            // The quad may be the printed tag's outline around a data square
            // too blurred to make a quad of its own.
            // Near the code's limit its reading must have every corner borne
            // out by the fit of the tag's model: the square is the outline's
            // middle half, not a quad of its own edges (on the wild set, one
            // at ct14's limit had an occluded corner 3.7 px off).
            let inner = data_square_within(img, q)?;
            read(
                img,
                &cand.estimated,
                &inner,
                centre,
                targets,
                &p.decode,
                ReadAs {
                    shown: shown_grid(img, &inner),
                    promising: Promising::Align,
                    glared: false,
                    rim: false,
                },
            )
            .filter(|d| {
                if d.occluded {
                    target_of(targets, d).is_some_and(|t| occluded_reading_stands(img, d, t, p))
                } else {
                    d.likelihood
                        || target_of(targets, d)
                            .is_some_and(|t| outline_reading_stands(img, d, t, p))
                }
            })
            .and_then(|d| unless_faint(img, d, targets, p))
            .map(|det| Reading { det, outline: true })
        });
    if reading.is_some() {
        return Outcome::Read(reading.map(Box::new));
    }
    match last_resort {
        Some(det) => Outcome::LastResort(Box::new(Reading {
            det,
            outline: false,
        })),
        None => match look {
            Some(look) if look >= UNREAD_MIN_LOOK && small_enough_to_align(q, targets) => {
                Outcome::Unread(Box::new(Unread {
                    quad: *q,
                    estimated: cand.estimated,
                    centre,
                    look,
                }))
            }
            _ => Outcome::Read(None),
        },
    }
}

/// Small moves of the aligned print's square that the rim look reads the
/// cells at when they do not read where the print aligned: a scale about
/// its centre and a shift (px), within the alignment's own error (on the
/// wild set the aligned corners were 0.31 px from the truth at the
/// median, 0.74 px at the 90th percentile). Cells of 1.5-2 px read or not
/// on a third of a pixel near the limit of the blur: this read 37 more
/// markers of the wild set. Its readings by the nearest codeword are
/// refused: with them, one more marker read, and one reading's hidden
/// corner was 3.4 px off.
const ALIGNED_JITTER: [(f64, [f64; 2]); 6] = [
    (1.0, [0.35, 0.0]),
    (1.0, [-0.35, 0.0]),
    (1.0, [0.0, 0.35]),
    (1.0, [0.0, -0.35]),
    (1.025, [0.0, 0.0]),
    (0.975, [0.0, 0.0]),
];

/// Largest cell (px) of a square the rim look reads at the moves of
/// [`ALIGNED_JITTER`]: on larger cells a third of a pixel does not decide
/// a reading. The markers the moves read on the wild set had cells of at
/// most 3.1 px (ct14 squares of 49 px), while on the wild benchmark's
/// 1080p frames, rims of larger squares that read nowhere cost 1.5-5 ms
/// of moves each.
const JITTER_MAX_CELL_PX: f64 = 3.2;

/// The reading of a rim candidate: first on the corners of the aligned
/// print, read as they are (refinement measures sides, and a blurred data
/// square has no side of its own to measure), then at small moves of them
/// ([`ALIGNED_JITTER`]), then, when no reading stands, on the predicted
/// quad refined, and last, where some reading of the rim named an id, on
/// the aligned print's square refined. Readings by the nearest codeword
/// are refused on the refined quads: of the rim look's occluded readings
/// on such quads on the wild set 4 of 21 had a corner 3-14 px off, where
/// an occluder's edge was taken for a side. On the aligned print they
/// stand when the fit sees every corner (`rim_reading_stands`).
#[allow(clippy::too_many_arguments)]
fn rim_attempt(
    img: &GrayView<'_>,
    cand: &Candidate,
    seen: &rim::RimSeen,
    scale: f64,
    centre: [f64; 2],
    targets: &[Target],
    p: &DecodingParams,
    scratch: &mut RefineScratch,
) -> Outcome {
    // The reading of the cells at `q`, if it stands; `aligned`, the
    // aligned print's corners it reports (none: the fit's); `shown`, the
    // grid the square shows (`pitch::shown_grid`); `promising`, what a
    // leading codeword leads to. Only the aligned print's reading aligns
    // the quad to it: the others' quads are small moves of that quad or
    // the refined one (`Promising::Smear`).
    // A reading kept only as a last resort (shaded, or at the rings'
    // clear levels: see `standing`) stands nowhere in the rim look: with
    // the shaded ones of every quad the wild set gained 40 markers, two
    // with a corner over 3 px off at a sigma of 0.65 and 2.4 px (both on
    // small moves of the print, where a third of a pixel decided the
    // reading). The aligned print's own reading, when no fit confirms it,
    // is kept aside as a last resort (`unfitted_on_aligned`); so is its
    // shaded reading where the fit confirms it as it would any rim
    // reading (`rim_reading_stands`), its hidden corners then held to
    // [`HIDDEN_FIT_SIGMA_PX`] (`last_resort_stands`). Glared and blurred
    // tags of 24-45 px read so: on the wild set 14 more markers, on the
    // calibration set 6, none rough or lost; without the sigma bound 16
    // and one rough (an estimated corner 3.1 px off at a sigma of 2.4 px)
    // once the print and the fit may disagree by 0.06 of the side. Its
    // reading under glare (`decode::QuadReading::glared`) is kept aside
    // the same way, and stands only with every corner seen
    // (`glare_standing`, see `Decoded::last_resort`).
    let aside_slot: std::cell::Cell<Option<Detection>> = std::cell::Cell::new(None);
    // Whether some reading so far named an id, standing or not.
    let named = std::cell::Cell::new(false);
    let unfit = FitsFailed::default();
    let on =
        |q: &[[f64; 2]; 4], aligned: Option<&[[f64; 2]; 4]>, occluded: bool, shown, promising| {
            let how = ReadAs {
                shown,
                promising,
                glared: promising == Promising::Align,
                rim: true,
            };
            let d = read(img, &cand.estimated, q, centre, targets, &p.decode, how);
            named.set(named.get() || d.is_some());
            let d = d.filter(|d| occluded || !d.occluded)?;
            // The rim look's one test of a reading, on this quad.
            let stands =
                |d| rim_reading_stands(img, d, targets, p, &seen.ellipse, scale, aligned, &unfit);
            if d.last_resort {
                if promising == Promising::Align {
                    // Still marked a last resort: `last_resorts` takes it.
                    aside_slot.set(stands(d));
                }
                return None;
            }
            if promising != Promising::Align {
                return stands(d);
            }
            let kept = d.clone();
            let fitted = stands(d);
            if fitted.is_none() {
                aside_slot.set(unfitted_on_aligned(kept, targets, &seen.ellipse, scale));
            }
            fitted
        };
    // The moves read as the grid their square shows: they move it by a
    // third of a pixel.
    let jittered = |q: &[[f64; 2]; 4], shown| {
        let c = centroid(q);
        ALIGNED_JITTER.iter().find_map(|&(k, d)| {
            let m = q.map(|p| {
                [
                    c[0] + k * (p[0] - c[0]) + d[0],
                    c[1] + k * (p[1] - c[1]) + d[1],
                ]
            });
            on(&m, Some(q), false, shown, Promising::Smear)
        })
    };
    let aligned = seen.aligned(img).map(|q| (q, shown_grid(img, &q)));
    // A print aligned as another family's tag is not refined and read
    // again: the refined quad is the same square.
    if let Some((q, _)) = aligned.filter(|&(_, shown)| none_can_read(shown, targets)) {
        return Outcome::Foreign(Box::new(q));
    }
    // One that shows no grid clearly may still read as a tag of a
    // built-in family not looked for: a small one of the other family.
    if let Some((q, None)) = aligned {
        if reads_as_other_family(img, &q, p) {
            return Outcome::Foreign(Box::new(q));
        }
    }
    // A print aligned smaller than any target's rim reading may stand at
    // is not read: each of its readings would fail that test after a
    // model fit.
    if aligned.is_some_and(|(q, _)| targets.iter().all(|t| too_small_for_rim(&q, t))) {
        return Outcome::Read(None);
    }
    // A candidate's quad refined and read, unless faint.
    let mut read_refined = |c: &Candidate| {
        let q = refine_candidate(img, c, scale, &p.refine, scratch);
        on(&q, None, false, shown_grid(img, &q), Promising::Smear)
            .and_then(|d| unless_faint(img, d, targets, p))
    };
    let reading = aligned
        .and_then(|(q, shown)| {
            on(&q, Some(&q), true, shown, Promising::Align).or_else(|| {
                // The moves only where a third of a pixel matters: cells
                // of at most JITTER_MAX_CELL_PX in the family with the most.
                (mean_side(&q) <= JITTER_MAX_CELL_PX * most_cells(targets))
                    .then(|| jittered(&q, shown))
                    .flatten()
            })
        })
        .or_else(|| read_refined(cand))
        .or_else(|| {
            // Refinement measures the sides in windows of a cell or two
            // around the quad it starts from: the aligned print lies a
            // pixel or so from the square, the rim's prediction a tenth of
            // the side, and from there refinement can follow an occluder's
            // edge. On the wild set the predicted quad refined to 2.5-5 px
            // from the aligned print where this read 4 more markers (30-43
            // px, under flush tape, an occluder over one side, a glare;
            // every corner within 1.9 px of the truth). Only where an id
            // was named: a rim of clutter names none, and refining every
            // failing rim's print cost 1.5% of the wild set's median time
            // for no more markers there (one more of the calibration
            // set's).
            let (a, _) = aligned.filter(|_| named.get())?;
            read_refined(&rim::moved_to(cand, &a, scale))
        })
        .map(|det| Reading {
            det,
            outline: false,
        });
    let aside = |det| {
        Box::new(Reading {
            det,
            outline: false,
        })
    };
    // A reading that stood after the aligned print's own did not (at a
    // small move of the print, or on the refined quad) keeps that one as
    // a last resort: the verify stage may drop it (on the wild set 5
    // markers were lost so, on the calibration set 3).
    match (reading, aside_slot.into_inner()) {
        (None, Some(det)) => Outcome::LastResort(aside(det)),
        (Some(r), Some(det)) => Outcome::ReadKeeping(Box::new(r), aside(det)),
        (reading, None) => Outcome::Read(reading.map(Box::new)),
    }
}

/// Whether the grid a square shows (`shown`, [`shown_grid`]) rules out
/// every target family; never when it shows none.
fn none_can_read(shown: Option<usize>, targets: &[Target]) -> bool {
    shown.is_some_and(|g| targets.iter().all(|t| rules_out(g, &t.family)))
}

/// Whether a code reading of a data square taken inside an outline
/// stands: one that would stand without a fit ([`stands_unfit`]), or the
/// model fit supporting all four corners.
fn outline_reading_stands(
    img: &GrayView<'_>,
    d: &Detection,
    t: &Target,
    p: &DecodingParams,
) -> bool {
    if stands_unfit(d, t) {
        return true;
    }
    matches!(
        verify_reading(img, d, t, p),
        Verdict::Fitted(v) if v.unsupported.iter().all(|&u| !u)
    )
}

/// Farthest the disc rim a rim reading's fit puts on the image may lie
/// from the rim measured ([`rim::rim_disagreement`]), as a share of the
/// data square's side. On the wild set the right readings of the rim look
/// put it at most 0.21 of the side away (the fit and the rim's ellipse
/// are both uncertain on 20-30 px tags), the readings whose fit took an
/// occluder's edge for a side 0.16-0.48.
const RIM_AGREEMENT_OF_SIDE: f64 = 0.25;

/// Smallest cell (px) of a tag read by the rim look: the smallest data
/// squares the detector is meant to read (ct14 at 24 px, ct8 at 20 px)
/// have cells of 1.5 and 2 px. Below it a rim reading has only cells
/// blurred into each other to place its corners by: on the wild set the
/// one rim reading with a corner over 3 px off (3.07 px) was a ct14 tag of
/// 22.5 px smeared by motion, its fit's own sigma 0.2-1.1 px.
pub(super) const RIM_MIN_CELL_PX: f64 = 1.5;

/// Farthest (share of the side) a corner of the print aligned by the rim
/// look may lie from the one the fit of the read tag's model puts it at.
/// The two are independent: the print's fixed look against the read
/// cells' edges. On the wild set the readings that stood disagreed by at
/// most 0.105 of the side.
const RIM_ALIGN_AGREEMENT_OF_SIDE: f64 = 0.15;

/// A reading `d` of a rim candidate (`quads::Candidate::rim`, the rim `e`
/// of the look of scale `scale`), if it stands: its tag's model fits
/// ([`Verdict::Fitted`]: neither unfit nor contradicted by the fit), the
/// fit puts the disc rim where it was measured ([`RIM_AGREEMENT_OF_SIDE`])
/// and the tag has cells of at least [`RIM_MIN_CELL_PX`].
///
/// Read on the `aligned` print's corners, the reading reports those, in
/// its own order, when they lie within [`RIM_ALIGN_AGREEMENT_OF_SIDE`] of
/// the fit's (on the wild set they were the closer to the truth: 0.31 px
/// at the median against the fit's 0.75), and an occluded one stands only
/// where the fit gives every corner a sigma. Read on the refined
/// prediction (`aligned` none), it reports the fit's corners: the quad's
/// came from the rim's prediction, with sides measured from it, and on the
/// wild set the fit's were the closer (one reading kept on its own corners
/// was 3.1 px off on a 26 px tag, its fit 2.6 px). `unfit`: the look's
/// readings whose fit is known not to stand ([`FitsFailed`]).
#[allow(clippy::too_many_arguments)]
fn rim_reading_stands(
    img: &GrayView<'_>,
    d: Detection,
    targets: &[Target],
    p: &DecodingParams,
    e: &super::ellipses::Ellipse,
    scale: f64,
    aligned: Option<&[[f64; 2]; 4]>,
    unfit: &FitsFailed,
) -> Option<Detection> {
    let t = target_of(targets, &d)?;
    if unfit.holds(&d) {
        return None;
    }
    let v = match verify_reading(img, &d, t, p) {
        Verdict::Fitted(v) => v,
        _ => return None,
    };
    if !rim_geometry_agrees(&v.homography, &v.corners, t, e, scale) {
        unfit.add(&d);
        return None;
    }
    let Some(aligned) = aligned else {
        return Some(Detection {
            corners: v.corners,
            center: v.homography.map([0.0, 0.0]).unwrap_or(d.center),
            homography: v.homography,
            placed: true,
            ..d
        });
    };
    on_aligned_print(d, &v, aligned)
}

/// The readings of one rim look whose tag model fit put the disc rim or
/// the square's size where a rim reading cannot stand
/// (`rim_geometry_agrees`), by family, id and the kind of reading (which
/// readings may confirm the fit): the look's later readings of the same
/// kind and id, at small moves of the print or on the refined quad, are
/// not fitted again.
///
/// Why: the fit starts from the reading's corners but converges to the
/// tag's edges: on the wild benchmark's 1080p frame 5 a ct14 tag of
/// 23.5 px (a rim reading needs 24 px) was read at the print and at every
/// move of it, and the nine fits all put its corners within 0.05 px of
/// each other, each too small; the frame took 16-17 ms instead of
/// 19-21 ms. Not for fits that failed outright (unfit or contradicted):
/// those depend on their start more, and skipping them lost a marker of
/// the calibration set. As it is, of the wild set's 3000 frames four
/// changed: one tag's corners closer to the truth (0.76 to 0.29 px at
/// worst), three others on the same corners but now reported from the
/// aligned print alone (`unfitted_on_aligned`: every corner estimated,
/// each within twice its sigma), where a later move's fit had stood
/// before; the calibration, jitter and tag-free sets are unchanged.
#[derive(Default)]
struct FitsFailed(std::cell::RefCell<Vec<(String, u64, [bool; 4])>>);

impl FitsFailed {
    /// The kind of reading `d` is, as the fit's confirmation depends on it.
    fn kind(d: &Detection) -> [bool; 4] {
        [d.occluded, d.likelihood, d.faint, d.glared]
    }

    fn holds(&self, d: &Detection) -> bool {
        let kind = Self::kind(d);
        self.0
            .borrow()
            .iter()
            .any(|(family, id, k)| *family == d.family && *id == d.id && *k == kind)
    }

    fn add(&self, d: &Detection) {
        self.0
            .borrow_mut()
            .push((d.family.clone(), d.id, Self::kind(d)));
    }
}

/// Share of the smallest data square a rim reading stands on
/// ([`RIM_MIN_CELL_PX`] cells) under which the rim look does not read the
/// print it aligned ([`too_small_for_rim`]). A reading's square is the
/// model fit's, which moves the aligned print's corners by a pixel or so
/// (at most [`RIM_ALIGN_AGREEMENT_OF_SIDE`] of the side, or the reading
/// does not stand), and the small moves read at scales of 0.975-1.025:
/// squares a tenth under the limit cannot reach it.
const RIM_SIDE_SLACK: f64 = 0.9;

/// Whether the square `q` is too small for a rim reading of target `t`
/// to stand (`rim_geometry_agrees`), with [`RIM_SIDE_SLACK`]: the rim
/// look reads no such target there, and reads nothing at all where no
/// target is left.
///
/// Why: such squares were read anyway, at the aligned print and at each
/// small move of it, and every reading that named an id paid for a model
/// fit before the size test dropped it. On the wild benchmark's 1080p
/// frames 2 and 14, prints aligned at 20 px (a ct14 rim reading needs
/// 24 px; the small-tag look reads such tags) took the rim stage's time
/// from 1.3 ms to 2.5-3.5 ms, with or without ct8 looked for. No
/// detection of the wild, calibration, jitter or tag-free sets changes.
fn too_small_for_rim(q: &[[f64; 2]; 4], t: &Target) -> bool {
    mean_side(q) < RIM_SIDE_SLACK * rim_min_side(t)
}

/// Whether a rim reading's geometry, `h` and the data square `corners` it
/// maps, of target `t`'s family, puts the disc rim where it was measured
/// (`e`, of the look of scale `scale`: [`RIM_AGREEMENT_OF_SIDE`]) and has
/// cells of at least [`RIM_MIN_CELL_PX`].
fn rim_geometry_agrees(
    h: &Homography,
    corners: &[[f64; 2]; 4],
    t: &Target,
    e: &super::ellipses::Ellipse,
    scale: f64,
) -> bool {
    !(rim::rim_disagreement(h, e, scale) > RIM_AGREEMENT_OF_SIDE
        || mean_side(corners) < rim_min_side(t))
}

/// Smallest data square (mean side, px) a rim reading of target `t`
/// stands on: [`RIM_MIN_CELL_PX`] over the family's cells and margin.
fn rim_min_side(t: &Target) -> f64 {
    RIM_MIN_CELL_PX * (t.family.grid() + MARGIN_CELLS) as f64
}

/// Share of the side that is the sigma of each corner of a reading placed
/// on the aligned print with no fit confirming it ([`unfitted_on_aligned`]).
/// [`RIM_SIGMA_OF_SIDE`], the floor of a rim reading's sigma on top of its
/// fit's, and a fifth more, with no fit to add its own. On the calibration
/// set (`make calibrate-sigma`) the 9 markers found so had corners at most
/// 0.026 of their side off, all within twice this sigma (too few to choose
/// a share by); on the wild set 155 of the 156 corners of its 39.
const UNFITTED_SIGMA_OF_SIDE: f64 = 0.03;

/// The rim look's reading `d` made on the aligned print's corners, when the
/// fit of its tag's model does not confirm it (`rim_reading_stands`): on
/// blurred and glared tags of 22-47 px the fit, of edges a pixel or two
/// wide, crept off where the print's whole fixed look had placed the
/// square (on the wild set, of the 105 markers whose rim look read their
/// right id there and whose fit contradicted the reading, the aligned
/// corners of 90 were within a pixel of the truth and of 99 within two).
/// It is kept as a last resort: every corner estimated, each with a sigma
/// of [`UNFITTED_SIGMA_OF_SIDE`] of the side, where the disc rim the
/// reading's geometry puts on the image agrees with the rim measured
/// ([`RIM_AGREEMENT_OF_SIDE`]) and the square is no smaller than a rim
/// reading's ([`RIM_MIN_CELL_PX`]). Occluded readings (by the nearest
/// codeword) are kept too, although on the aligned print with a fit they
/// stand only where the fit gives every corner a sigma
/// ([`on_aligned_print`]): here no corner is taken as measured. Of the
/// markers this found, 12 of the wild set's 39 and 1 of the calibration
/// set's 9 were such readings, every corner within 1.4 px of the truth.
fn unfitted_on_aligned(
    d: Detection,
    targets: &[Target],
    e: &super::ellipses::Ellipse,
    scale: f64,
) -> Option<Detection> {
    let t = target_of(targets, &d)?;
    if !rim_geometry_agrees(&d.homography, &d.corners, t, e, scale) {
        return None;
    }
    let side = mean_side(&d.corners);
    Some(Detection {
        estimated: [true; 4],
        corner_sigma: Some([UNFITTED_SIGMA_OF_SIDE * side; 4]),
        placed: true,
        unfitted: true,
        ..d
    })
}

/// Reading `d` reported on the `aligned` print's corners, in its own
/// order, if they lie within [`RIM_ALIGN_AGREEMENT_OF_SIDE`] of the
/// corners `v`, the fit of its tag's model, puts (on the wild set the
/// aligned corners were the closer to the truth: 0.31 px at the median
/// against the fit's 0.75), an occluded reading only where the fit gives
/// every corner a sigma.
fn on_aligned_print(d: Detection, v: &Verified, aligned: &[[f64; 2]; 4]) -> Option<Detection> {
    let side = mean_side(&v.corners);
    let (gap, corners) = nearest_turn(aligned, &v.corners);
    // An occluded reading (by the nearest codeword) stands only where
    // the fit sees every corner, as a quad's does
    // (`occluded_reading_stands`): on the wild set, of 56 such rim
    // readings the three whose fit left a corner without a sigma included
    // the one with a corner over 3 px off (3.7 px, its fit agreeing).
    if gap > RIM_ALIGN_AGREEMENT_OF_SIDE * side
        || (d.occluded && !v.sigma.iter().all(|s| s.is_finite()))
    {
        return None;
    }
    let homography = Homography::from_points(&CORNERS, &corners)?;
    Some(Detection {
        corners,
        center: homography.map([0.0, 0.0]).unwrap_or(d.center),
        homography,
        placed: true,
        ..d
    })
}

/// The aligned print's corners `aligned` in the order of `corners` (TL,
/// BL, BR, TR): the quarter turn that brings them nearest, with the
/// farthest distance (px) between the two squares' corners under it. The
/// code resolves a reading's turn; the print's bars and ears do too, but
/// are a pixel or two wide on the tags the print is aligned on.
fn nearest_turn(aligned: &[[f64; 2]; 4], corners: &[[f64; 2]; 4]) -> (f64, [[f64; 2]; 4]) {
    let turned = |k: usize| -> [[f64; 2]; 4] { std::array::from_fn(|i| aligned[(i + k) % 4]) };
    let gap = |c: &[[f64; 2]; 4]| {
        (0..4)
            .map(|i| norm(sub(c[i], corners[i])))
            .fold(0.0, f64::max)
    };
    (1..4)
        .map(turned)
        .fold((gap(aligned), *aligned), |best, c| {
            let g = gap(&c);
            if g.total_cmp(&best.0).is_lt() {
                (g, c)
            } else {
                best
            }
        })
}

/// Reading `d` as it is, unless it is faint (`decode::QuadReading::faint`:
/// read by likelihood at a contrast several times the one its frame and
/// margin show, where an occluder or glare over the frame may have moved
/// the quad). A faint reading stands only where the print's fixed look,
/// aligned to the image from its quad, correlates
/// ([`print_align::MIN_CORRELATION`]) and agrees with the fit of the read
/// tag's model ([`on_aligned_print`]), and is reported on the aligned
/// corners.
fn unless_faint(
    img: &GrayView<'_>,
    d: Detection,
    targets: &[Target],
    p: &DecodingParams,
) -> Option<Detection> {
    if !d.faint {
        return Some(d);
    }
    let t = target_of(targets, &d)?;
    let v = match verify_reading(img, &d, t, p) {
        Verdict::Fitted(v) => v,
        _ => return None,
    };
    let a = print_aligned_from(img, &d.corners)?;
    on_aligned_print(d, &v, &a)
}

/// The print's fixed look aligned to `img` from the quad `q` (TL, BL, BR,
/// TR, px) by [`print_align::align`], where it correlates: see
/// [`print_aligned_by`].
fn print_aligned_from(img: &GrayView<'_>, q: &[[f64; 2]; 4]) -> Option<[[f64; 2]; 4]> {
    print_aligned_by(img, q, print_align::align)
}

/// An alignment of the print from an affine prediction (matrix, centre),
/// as [`print_align::align`].
type PrintAligner = fn(&GrayView<'_>, [[f64; 2]; 2], [f64; 2]) -> Option<print_align::Aligned>;

/// The print's fixed look aligned to `img` from the quad `q` (TL, BL, BR,
/// TR, px) by `align` ([`print_align::align`] or
/// [`print_align::align_quickly`]), where it correlates
/// ([`print_align::MIN_CORRELATION`]): the aligned data square's corners,
/// in the print's own order. The quad, as the affine map of the tag's
/// plane it would be without perspective (tag units, the data square's
/// corners at +-0.5), is the alignment's starting point; the alignment
/// resolves the turn itself.
fn print_aligned_by(
    img: &GrayView<'_>,
    q: &[[f64; 2]; 4],
    align: PrintAligner,
) -> Option<[[f64; 2]; 4]> {
    let half = |a: usize, b: usize, k: usize| (q[a][k] + q[b][k]) / 2.0;
    // TL, BL, BR, TR at (-0.5,-0.5), (-0.5,0.5), (0.5,0.5), (0.5,-0.5).
    let m = [
        [half(2, 3, 0) - half(0, 1, 0), half(1, 2, 0) - half(0, 3, 0)],
        [half(2, 3, 1) - half(0, 1, 1), half(1, 2, 1) - half(0, 3, 1)],
    ];
    align(img, m, centroid(q))
        .filter(|a| a.correlation >= print_align::MIN_CORRELATION)
        .map(|a| a.corners)
}

/// Farthest (px) a hidden corner of a reading under glare may lie from
/// where the print's fixed look, aligned from the fitted corners, puts it
/// ([`print_agrees_at`]): half the 3 px of a rough corner.
///
/// Why: a glare washes out the frame around the corners it covers, so the
/// fit of the tag's model has no edge there and places such a corner from
/// the rest of the tag, and its sigma is no sure guide (on the wild set,
/// glared readings kept with a hidden corner whatever the fit said had
/// three rough corners, 3.2-5.9 px off at sigmas of 0.6-0.9 px). The
/// print's alignment is a second, independent estimate: it matches the
/// whole fixed look (frame, disc, bars, ears) and leaves saturated pixels
/// out. Chosen on the calibration set (`make calibrate-sigma`'s set): of
/// its glared readings with hidden corners, those whose aligned print lay
/// within 1.5 px of the fit had every hidden corner within 1.72 px of the
/// truth, while one 5.3 px from it was 4.5 px off. On the wild set so,
/// 17 more markers, none rough or lost, every hidden corner within
/// 1.9 px.
const GLARE_PRINT_AGREEMENT_PX: f64 = 1.5;

/// Whether the print's fixed look, aligned to `img` from `corners` (a
/// fit's, TL, BL, BR, TR), puts every `hidden` corner within
/// [`GLARE_PRINT_AGREEMENT_PX`] of where `corners` has it, under the
/// quarter turn that brings the two squares nearest.
fn print_agrees_at(img: &GrayView<'_>, corners: &[[f64; 2]; 4], hidden: [bool; 4]) -> bool {
    let Some(aligned) = print_aligned_from(img, corners) else {
        return false;
    };
    let (_, turned) = nearest_turn(&aligned, corners);
    (0..4)
        .filter(|&i| hidden[i])
        .all(|i| norm(sub(turned[i], corners[i])) <= GLARE_PRINT_AGREEMENT_PX)
}

/// The target whose family detection `d` was read in.
fn target_of<'a>(targets: &'a [Target], d: &Detection) -> Option<&'a Target> {
    targets.iter().find(|t| t.family.name() == d.family)
}

/// [`verify`] of detection `d`, a reading of target `t`'s family.
/// Taken from the frame's [`Fits`] when it was made before.
fn verify_reading(img: &GrayView<'_>, d: &Detection, t: &Target, p: &DecodingParams) -> Verdict {
    let kind = Confirming {
        nearest: d.occluded,
        faint: d.faint,
        glared: d.glared,
        limit: t.max_corrected,
    };
    // A code reading near the code's limit is not held to its own
    // geometry (see `verify::verify`).
    let held = d.likelihood || stands_unfit(d, t);
    let key = p.fits.map(|_| FitKey {
        image: (
            img.data().as_ptr() as usize,
            img.width(),
            img.height(),
            img.stride(),
        ),
        family: d.family.clone(),
        id: d.id,
        corners: d.corners.map(|c| c.map(f64::to_bits)),
        contrast: d.contrast.to_bits(),
        corrected: d.corrected,
        kind: (kind.nearest, kind.faint, kind.glared, kind.limit),
        held,
    });
    if let Some(v) = p.fits.zip(key.as_ref()).and_then(|(f, k)| f.get(k)) {
        return v;
    }
    let v = verify(
        img,
        &t.family,
        d.id,
        &d.corners,
        d.contrast,
        d.corrected,
        kind,
        held,
        &p.decode,
    );
    if let Some((f, k)) = p.fits.zip(key) {
        f.put(k, v.clone());
    }
    v
}

/// Whether a reading by the nearest codeword ([`crate::nearest`]) stands:
/// the fit of the tag's model confirms it, and its corners pass
/// [`occluded_geometry_stands`] with the corners hidden from the quad or
/// unsupported by the fit ([`verify_one`] judges it again, on the corners
/// it ends with). Judged when the quad is read, so that a reading that
/// cannot stand does not keep the quad's other readings and its rivals
/// from coming.
fn occluded_reading_stands(
    img: &GrayView<'_>,
    d: &Detection,
    t: &Target,
    p: &DecodingParams,
) -> bool {
    matches!(occluded_standing(img, d, t, p), Standing::Stands)
}

/// How a reading by the nearest codeword stands (see
/// [`occluded_reading_stands`]).
enum Standing {
    Stands,
    /// Two or more hidden corners, each placed surely by the fit
    /// ([`hidden_fitted`]): see [`Decoded::last_resort`].
    LastResort,
    /// Under glare, hidden corners where the print's fixed look, aligned
    /// independently of the fit, puts them too
    /// ([`GLARE_PRINT_AGREEMENT_PX`]): a last resort tried after the
    /// tag's readings with every corner seen ([`last_resorts`]).
    PrintConfirmed,
    Falls,
}

/// How a quad's reading `d` stands: as a last resort when it is kept only
/// as one ([`Detection::last_resort`], [`Decoded::last_resort`]), as it is unless read by the nearest
/// codeword ([`occluded_standing`]).
fn standing(img: &GrayView<'_>, d: &Detection, targets: &[Target], p: &DecodingParams) -> Standing {
    match target_of(targets, d) {
        _ if d.last_resort => Standing::LastResort,
        _ if !d.occluded => Standing::Stands,
        Some(t) => occluded_standing(img, d, t, p),
        None => Standing::Falls,
    }
}

/// [`occluded_reading_stands`], telling a reading that stands as a last
/// resort ([`Decoded::last_resort`]) from one that falls.
fn occluded_standing(
    img: &GrayView<'_>,
    d: &Detection,
    t: &Target,
    p: &DecodingParams,
) -> Standing {
    match verify_reading(img, d, t, p) {
        Verdict::Fitted(v) if v.sigma.iter().all(|s| s.is_finite()) => {
            let hidden = hidden_corners(img, t, &v.corners, d.estimated, v.unsupported);
            // Under glare (`decode::QuadReading::glared`), every corner
            // seen, or the hidden ones where the aligned print puts them
            // (as a last resort, see `glare_standing`).
            if d.glared {
                return if !hidden.iter().any(|&h| h) {
                    Standing::LastResort
                } else if print_agrees_at(img, &v.corners, hidden) {
                    Standing::PrintConfirmed
                } else {
                    Standing::Falls
                };
            }
            if occluded_geometry_stands(&v.corners, hidden) {
                Standing::Stands
            } else if hidden_fitted(&v.sigma, hidden) {
                Standing::LastResort
            } else {
                Standing::Falls
            }
        }
        _ => Standing::Falls,
    }
}

/// Most cells of an estimated corner's frame and margin
/// ([`frame_misread_at_corners`]) that may misread for the corner to count
/// as seen, when the model fit supports all four corners: one, for a cell
/// blurred or cut by a thin stick.
const SEEN_CORNER_MISREADS: usize = 1;

/// [`SEEN_CORNER_MISREADS`] when the fit leaves some corner unsupported:
/// none. With one allowed, a calibration-set reading with an occluded
/// corner kept a corner 3.2 px off (rough on its 33 px tag) whose frame
/// and margin misread one cell.
const SEEN_CORNER_MISREADS_BESIDE_HIDDEN: usize = 0;

/// Which corners of a reading with fitted geometry `corners` count as
/// hidden for [`occluded_geometry_stands`]: those the quad `estimated` or
/// the model fit left `unsupported`, except an estimated corner the fit
/// supports whose frame and margin read as printed around it (at most
/// [`SEEN_CORNER_MISREADS`] cells misread, or
/// [`SEEN_CORNER_MISREADS_BESIDE_HIDDEN`] when another corner is
/// unsupported) or, when the fit supports all four corners, which lies
/// within [`HIDDEN_CORNER_TOL_PX`] of the parallelogram of the other
/// three.
///
/// Why: a stick across the data square cuts it into pieces whose quads
/// estimate corners that are in plain view, and such a reading, with two
/// estimated corners, was dropped however right it was (this keeps 47
/// more tags of the wild set, 33 of them occluded, 14 by sticks or
/// cables, every corner within 2.8 px of the truth; the corners stay
/// marked estimated). The fit's support alone
/// does not make a corner seen: counting every supported corner as
/// measured kept 5 readings on the wild set and 7 on the calibration set
/// with a corner 8-18 px off, placed where an occluder's edge meets a
/// side, and those had a corner the fit did not support; the
/// parallelogram test beside an unsupported corner kept one 3.2 px off.
fn hidden_corners(
    img: &GrayView<'_>,
    t: &Target,
    corners: &[[f64; 2]; 4],
    estimated: [bool; 4],
    unsupported: [bool; 4],
) -> [bool; 4] {
    let hidden: [bool; 4] = std::array::from_fn(|k| estimated[k] || unsupported[k]);
    // Only an estimated corner the fit supports may count as seen: with
    // none, nothing is read.
    if !(0..4).any(|k| estimated[k] && !unsupported[k]) {
        return hidden;
    }
    let misread = Homography::from_points(&CORNERS, corners)
        .and_then(|h| frame_misread_at_corners(img, t.family.grid(), &h))
        .unwrap_or([usize::MAX; 4]);
    if unsupported.iter().any(|&u| u) {
        return std::array::from_fn(|k| {
            hidden[k] && (unsupported[k] || misread[k] > SEEN_CORNER_MISREADS_BESIDE_HIDDEN)
        });
    }
    std::array::from_fn(|k| {
        hidden[k] && misread[k] > SEEN_CORNER_MISREADS && !near_parallelogram(corners, k)
    })
}

/// Whether corner `k` of `corners` lies within [`HIDDEN_CORNER_TOL_PX`] of
/// where the other three put it if the tag were seen without perspective
/// (the parallelogram they span).
fn near_parallelogram(corners: &[[f64; 2]; 4], k: usize) -> bool {
    parallelogram_gap(corners, k) <= HIDDEN_CORNER_TOL_PX
}

/// Distance (px) of corner `k` of `corners` from where the other three put
/// it if the tag were seen without perspective: the fourth corner of the
/// parallelogram they span.
fn parallelogram_gap(corners: &[[f64; 2]; 4], k: usize) -> f64 {
    let (a, o, b) = (
        corners[(k + 1) % 4],
        corners[(k + 2) % 4],
        corners[(k + 3) % 4],
    );
    let p = [a[0] + b[0] - o[0], a[1] + b[1] - o[1]];
    norm(sub(p, corners[k]))
}

/// Farthest (px) the one hidden corner of a nearest-codeword reading may
/// lie from where the other three put it if the tag were seen without
/// perspective (the parallelogram they span). Where an occluder hides a
/// corner, the quad's corner may be where the occluder's edge meets a
/// side, and the fit of the model, which sees no cells there, keeps it.
/// On the wild set, such readings with one hidden corner had it 0.1 to
/// 18 px from the truth; the 144 of 149 right ones within 3 px of the
/// parallelogram's corner (median 1.3 px: small tags show little
/// perspective), the 5 rough ones 5.6 to 18.6 px from it. A larger tag
/// shows more perspective and fails this test more often: the test may
/// lose it, not misplace it.
const HIDDEN_CORNER_TOL_PX: f64 = 3.0;

/// Whether the corners of a nearest-codeword reading, of which those
/// marked `hidden` were not measured, can be trusted: all four measured,
/// or one hidden within [`HIDDEN_CORNER_TOL_PX`] of the parallelogram of
/// the other three. Two hidden corners have nothing to check them by.
fn occluded_geometry_stands(corners: &[[f64; 2]; 4], hidden: [bool; 4]) -> bool {
    let mut hid = (0..4).filter(|&k| hidden[k]);
    match (hid.next(), hid.next()) {
        (None, _) => true,
        (Some(k), None) => near_parallelogram(corners, k),
        (Some(_), Some(_)) => false,
    }
}

/// Largest one-sigma uncertainty (px) the model fit may give each hidden
/// corner of a nearest-codeword reading with two or more of them
/// ([`hidden_corners_fitted`]): twice it is the 3 px of a rough corner.
/// On the wild set, 20 readings of the right id were dropped for hidden
/// corners the quad could not check (two or more, or one off the
/// parallelogram of the others), every corner within 2.9 px of the truth.
/// Kept with any sigma, they found 14 more markers there, 7 on the ct8
/// twin and 6 on the sigma calibration set, but one of the latter had a
/// hidden corner 5.5 px off (at a sigma of 5 px). Kept as this rule does
/// (two or more hidden, each within 1.5 px): 4 and 3 more (none on the
/// calibration set), none rough, each corner within 2 sigma of the truth.
const HIDDEN_FIT_SIGMA_PX: f64 = 1.5;

/// Whether a reading under an occluder with two or more hidden corners,
/// which nothing on the quad checks ([`occluded_geometry_stands`]), has
/// them placed closely enough by the model fit of its visible edges: each
/// with a sigma of at most [`HIDDEN_FIT_SIGMA_PX`]. Not for a reading of
/// an upsampled small-tag region, whose fit of cells 1-2 px wide is
/// surer than it is right (on the wild set, a hidden corner 1.15 px off
/// at a sigma of 0.14 px).
fn hidden_corners_fitted(d: &Detection, hidden: [bool; 4]) -> bool {
    match d.corner_sigma {
        Some(sigma) if d.occluded && !d.upsampled => hidden_fitted(&sigma, hidden),
        _ => false,
    }
}

/// Whether two or more corners are `hidden`, each with a sigma (`sigma`)
/// of at most [`HIDDEN_FIT_SIGMA_PX`] (see [`hidden_corners_fitted`]).
fn hidden_fitted(sigma: &[f64; 4], hidden: [bool; 4]) -> bool {
    hidden.iter().filter(|&&h| h).count() >= 2
        && (0..4).all(|k| !hidden[k] || sigma[k] <= HIDDEN_FIT_SIGMA_PX)
}

/// Farthest a hidden corner of a reading near its code's limit may lie
/// from the parallelogram of the other three corners, as a fraction of
/// the mean side (see [`hidden_corners_plausible`]). On the wild set the
/// hidden corners of the right readings near the limit lay at most 0.144
/// of the side from it (on tags of 17 to 50 px; perspective and the
/// estimate's own error both count), on the calibration set at most
/// 0.131; the one misplaced (a white triangle's edge taken for a side, a
/// corner 15.6 px off on a 44 px tag) lay 0.26 of the side from it.
const HIDDEN_CORNER_TOL_OF_SIDE: f64 = 0.2;

/// Whether the `hidden` corners of a reading near its code's limit (one
/// that would not stand without its fit, [`stands_unfit`]) lie where a
/// square seen in perspective could put them: each within
/// [`HIDDEN_CORNER_TOL_OF_SIDE`] of the quad's mean side from the fourth
/// corner of the parallelogram of the other three ([`parallelogram_gap`]).
/// Such a reading's cells confirm little, and the fit places a hidden
/// corner from the visible edges alone, which may include an occluder's
/// edge running into the frame. A loose test: it keeps every right reading
/// of the wild and calibration sets and cannot judge a misplaced corner
/// that stays near the parallelogram.
fn hidden_corners_plausible(corners: &[[f64; 2]; 4], hidden: [bool; 4]) -> bool {
    let tol = HIDDEN_CORNER_TOL_OF_SIDE * mean_side(corners);
    (0..4)
        .filter(|&k| hidden[k])
        .all(|k| parallelogram_gap(corners, k) <= tol)
}

/// Centroid of a candidate's corners at full resolution.
pub(super) fn centre_of(cand: &Candidate, scale: f64) -> [f64; 2] {
    centroid(&cand.corners.map(|q| to_full(q, scale)))
}

/// What becomes of a candidate given the tags found so far ([`plan`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Plan {
    /// Not decoded, and not counted.
    Skip,
    /// Decoded: a new tag, or a rival reading of found tag `Some(r)`.
    Decode(Option<usize>),
    /// A rival of found tag `r` that cannot win ([`RIVAL_MIN_SIDE`]):
    /// counted as a rival that did not read, without being decoded.
    Dismiss(usize),
}

/// Whether a candidate with centroid `centre` (and `scale`, the working
/// image's) is decoded given the tags `found` and the squares `foreign`
/// (see [`Decoded::foreign`]) so far, and as what.
pub(super) fn plan(
    cand: &Candidate,
    centre: [f64; 2],
    scale: f64,
    found: &[Found],
    foreign: &[Quad],
    p: &DecodingParams,
) -> Plan {
    let Some(r) = found
        .iter()
        .position(|f| inside(&f.reading.det.corners, centre))
    else {
        if foreign.iter().any(|q| inside(q, centre)) {
            return Plan::Skip;
        }
        return Plan::Decode(None);
    };
    // A linked candidate (see `quads`) over a tag already read is
    // never its rival: on large tags the cells bridge each other and
    // make many of them. Nor is a guessed one: three of its corners are
    // a parallelogram's, and a reading of it that beats the tag's own
    // would only be worse placed.
    if cand.linked || cand.guessed {
        return Plan::Skip;
    }
    // A tag read inside an outline keeps its rivals: a quad of its own
    // data square may still come.
    let f = &found[r];
    let settled = f.reading.det.corrected == 0 && !f.reading.outline;
    if settled || f.rivals >= p.max_rivals {
        return Plan::Skip;
    }
    let side = mean_side(&cand.corners.map(|q| to_full(q, scale)));
    if side < RIVAL_MIN_SIDE * mean_side(&f.reading.det.corners) {
        return Plan::Dismiss(r);
    }
    Plan::Decode(Some(r))
}

/// The sequential decoding loop: each candidate in turn skipped
/// ([`plan`]) or decoded, the [`Outcome`] of candidate `j` (centroid
/// `centre`) from `outcome`; a refused rival counts as one that did not
/// read. `taken(j, found, foreign)` sees the tags and the squares of
/// families not decoded found so far after each outcome was taken into
/// them.
pub(super) fn decode_in_order(
    candidates: &[Candidate],
    scale: f64,
    p: &DecodingParams,
    mut outcome: impl FnMut(usize, [f64; 2]) -> Outcome,
    mut taken: impl FnMut(usize, &[Found], &[Quad]),
) -> Decoded {
    let mut found: Vec<Found> = Vec::new();
    let mut foreign: Vec<Quad> = Vec::new();
    let mut last_resort: Vec<Found> = Vec::new();
    let mut unread: Vec<Unread> = Vec::new();
    let mut attempts = 0;
    // Candidates decoded to nothing since the last reading.
    let mut in_vain = 0;
    for (j, cand) in candidates.iter().enumerate() {
        if attempts >= p.max_attempts || in_vain >= p.max_in_vain_run {
            break;
        }
        let centre = centre_of(cand, scale);
        let (rival, outcome) = match plan(cand, centre, scale, &found, &foreign, p) {
            Plan::Skip => continue,
            // Dismissed unread, as if refused.
            Plan::Dismiss(r) => (Some(r), Outcome::Refused),
            Plan::Decode(rival) => (rival, outcome(j, centre)),
        };
        match (rival, outcome) {
            // A refused rival counts as one that did not read.
            (Some(r), Outcome::Refused) => found[r].rivals += 1,
            (None, Outcome::Refused) => {}
            (rival, Outcome::Read(best)) => {
                attempts += 1;
                in_vain = if best.is_some() { 0 } else { in_vain + 1 };
                take_reading(&mut found, rival, best.map(|b| *b));
            }
            // Read to nothing; kept for `aligned_unread` unless it is a
            // rival, whose centre lies in a tag found.
            (rival, Outcome::Unread(u)) => {
                attempts += 1;
                in_vain += 1;
                take_reading(&mut found, rival, None);
                if rival.is_none() {
                    unread.push(*u);
                }
            }
            (rival, Outcome::ReadKeeping(best, r)) => {
                attempts += 1;
                in_vain = 0;
                take_reading(&mut found, rival, Some(*best));
                last_resort.push(Found {
                    reading: *r,
                    rivals: 0,
                });
            }
            // Decoded to nothing that stands now.
            (rival, Outcome::LastResort(r)) => {
                attempts += 1;
                in_vain += 1;
                take_reading(&mut found, rival, None);
                last_resort.push(Found {
                    reading: *r,
                    rivals: 0,
                });
            }
            // A rival showing another family's grid read nothing.
            (Some(r), Outcome::Foreign(_)) => {
                attempts += 1;
                in_vain = 0;
                found[r].rivals += 1;
            }
            (None, Outcome::Foreign(q)) => {
                attempts += 1;
                in_vain = 0;
                foreign.push(*q);
            }
        }
        taken(j, &found, &foreign);
    }
    Decoded {
        found,
        foreign,
        attempts,
        last_resort,
        unread,
    }
}

/// Takes a candidate's reading `best` into the tags `found`: a rival of
/// tag `rival` if it lies inside one, else perhaps a new tag.
fn take_reading(found: &mut Vec<Found>, rival: Option<usize>, best: Option<Reading>) {
    match (rival, best) {
        (Some(r), Some(b)) => {
            let f = &mut found[r];
            f.rivals += 1;
            // Only a reading of the same tag competes; a different
            // id inside a found tag is not trusted over it.
            let same = b.det.family == f.reading.det.family && b.det.id == f.reading.det.id;
            if same && b.beats(&f.reading) {
                f.reading = b;
            }
        }
        (Some(r), None) => found[r].rivals += 1,
        (None, Some(b)) => found.push(Found {
            reading: b,
            rivals: 0,
        }),
        (None, None) => {}
    }
}

/// Cells across the data grid of the finest family detected.
fn finest_grid(p: &RefineParams) -> usize {
    (p.cells_per_side as usize).saturating_sub(MARGIN_CELLS)
}

/// How [`read`] reads a quad.
#[derive(Debug, Clone, Copy)]
struct ReadAs {
    /// The grid the square shows ([`shown_grid`]), whose families alone it
    /// is read as.
    shown: Option<usize>,
    /// What a likelihood fit that leads without reading leads to.
    promising: Promising,
    /// Whether the reading under glare by the nearest codeword
    /// (`decode::QuadReading::glared`) is tried: for a candidate's own
    /// quad and the rim look's aligned print, where it is kept aside as a
    /// last resort and the readings that follow are still tried. On the
    /// outline's inner square and at the rim look's other quads (small
    /// moves of the print, refined quads) it would stand in for the
    /// readings those go on to try when nothing reads.
    glared: bool,
    /// Whether the quad is the rim look's: no family is read where its
    /// rim readings could not stand ([`too_small_for_rim`]).
    rim: bool,
}

/// The best reading of the refined quad `q` over the target families: the
/// fewest corrections, the first family on a tie. `centre` (the quad's
/// centroid) stands in for the tag centre if the homography cannot map it.
fn read(
    img: &GrayView<'_>,
    estimated: &[bool; 4],
    q: &[[f64; 2]; 4],
    centre: [f64; 2],
    targets: &[Target],
    params: &DecodeParams,
    how: ReadAs,
) -> Option<Detection> {
    let mut best: Option<Detection> = None;
    for t in targets {
        // A clean read cannot be beaten by another family.
        if best.as_ref().is_some_and(|b| b.corrected == 0) {
            break;
        }
        if how.rim && too_small_for_rim(q, t) {
            continue;
        }
        // A family whose grid the square does not show cannot read
        // (`pitch`), and its readings are the costliest of a frame that
        // holds the other family's tags.
        if how.shown.is_some_and(|g| rules_out(g, &t.family)) {
            continue;
        }
        // A reading by the code over the family's limit counts as none,
        // so that the grid's other readings are tried.
        let accept = Accept {
            nearest: true,
            limit: Some(t.max_corrected),
            smeared: !estimated.iter().any(|&e| e),
            promising: how.promising,
            glared: how.glared,
        };
        let Some(r) = decode_quad_by(img, &t.family, q, params, accept) else {
            continue;
        };
        if best.as_ref().is_some_and(|b| b.corrected <= r.corrected) {
            continue;
        }
        let d = r.rotation % 4;
        let estimated = std::array::from_fn(|c| estimated[(c + 4 - d) % 4]);
        let Some(h) = Homography::from_points(&CORNERS, &r.corners) else {
            continue;
        };
        let center = h.map([0.0, 0.0]).unwrap_or(centre);
        best = Some(Detection {
            family: t.family.name().to_string(),
            id: r.id,
            corners: r.corners,
            estimated,
            corner_sigma: None,
            corrected: r.corrected,
            likelihood: r.likelihood,
            occluded: r.occluded,
            upsampled: false,
            placed: false,
            faint: r.faint,
            last_resort: r.shaded || r.clear_ring || r.glared,
            glared: r.glared,
            unfitted: false,
            center,
            contrast: r.contrast,
            homography: h,
        });
    }
    best
}

/// Reed-Solomon symbols a reading must leave unused below its family's
/// limit to stand without the verify stage's model fit (a tag too small or
/// too hidden to fit). Readings near or over the limit (the latter lean on
/// erasures, see [`crate::decode::within_limit`]) are dropped unless the fit confirms
/// their geometry: on the wild set the unconfirmed ones at 9 to 10
/// corrections put corners 3.1, 4.5 and 14 px off, while the confirmed
/// ones were right.
const UNFIT_MARGIN: usize = 2;

/// One detection per physical tag, sorted by family and id. Candidates
/// overlapping an earlier find were skipped while decoding, but a later,
/// larger quad may still contain an earlier one: of two detections of
/// which one contains the other's centre, the better reading stays.
pub(crate) fn one_per_tag(found: Vec<Found>) -> Vec<Detection> {
    one_per_tag_indexed(found)
        .into_iter()
        .map(|(_, d)| d)
        .collect()
}

/// Whether detections `a` and `b` are of one physical tag: one contains
/// the other's centre ([`one_per_tag`]).
fn same_tag(a: &Detection, b: &Detection) -> bool {
    inside(&a.corners, b.center) || inside(&b.corners, a.center)
}

/// [`one_per_tag`], each detection with the index in `found` of the
/// reading it is.
pub(crate) fn one_per_tag_indexed(found: Vec<Found>) -> Vec<(usize, Detection)> {
    let mut kept: Vec<(usize, Reading)> = Vec::with_capacity(found.len());
    for (i, Found { reading: r, .. }) in found.into_iter().enumerate() {
        let d = &r.det;
        if let Some(o) = kept.iter_mut().find(|(_, o)| same_tag(&o.det, d)) {
            if r.beats(&o.1) {
                *o = (i, r);
            }
        } else {
            kept.push((i, r));
        }
    }
    let mut out: Vec<(usize, Detection)> = kept.into_iter().map(|(i, r)| (i, r.det)).collect();
    out.sort_by(|(_, a), (_, b)| a.family.cmp(&b.family).then(a.id.cmp(&b.id)));
    out
}

/// A fitted model replaces a detection's corners only when it moves one of
/// them by more than `KEEP_MOVE_PX` px or `KEEP_MOVE_SIDE` of the side
/// (the larger): such a move undoes a corner taken where an occluder's
/// edge continues a side. Smaller moves keep the sides' intersections,
/// which on large, sharp tags are the more accurate (the model fit carries
/// a bias of a few tenths of a pixel on 500 px tags, not yet understood).
const KEEP_MOVE_PX: f64 = 1.0;
/// Floor of the corner uncertainty of a tag read by the rim look, as a
/// share of its side: its corners are the model fit's on a tag too
/// blurred or small to make a quad of its own, and lie further from the
/// truth than the fit's sigma says (at the median twice, at the 90th
/// percentile six times as far, on the wild set). Chosen on the
/// calibration set (`make calibrate-sigma`, its rim readings alone) as the
/// smallest share on a 0.005 grid putting at least 95% of their corners
/// within 2 sigma (0.02: 90.4%, 0.025: 95.2%).
const RIM_SIGMA_OF_SIDE: f64 = 0.025;

/// Floor of the corner uncertainty of a tag whose fitted geometry was
/// confirmed by a reading as smeared by motion (`decode::Promising`), or
/// whose fit found its sides blurred as a smear blurs them
/// (`verify::SMEAR_SPREAD_PX`), as a share of its side: a smear widens
/// two of the data square's sides and rounds its corners off along it,
/// and the fit, which takes the edges for blurred evenly, places the
/// corners further from the truth than its sigma says (on the
/// calibration set 87.3% of those corners lay within 2 sigma, 65 tags; on
/// the wild set 88.7%, 208 tags). Chosen on the calibration set (`make
/// calibrate-sigma`) as the smallest share on a 0.005 grid putting at
/// least 95% of their corners within 2 sigma, as [`RIM_SIGMA_OF_SIDE`]
/// was (0.015: 92.7%, 0.02: 95.8%; on the wild set, 95.8% with 0.02).
const SMEAR_SIGMA_OF_SIDE: f64 = 0.02;

/// Factor on the corner uncertainty of a tag read by likelihood: such a
/// tag is small and blurred, and its corners sit further from the truth
/// than the fit's sigma (with its blur term) says. Chosen with
/// `verify::BLUR_BIAS` on the calibration set (`make calibrate-sigma`) as
/// the smallest factor on a 0.1 grid that puts 90% of those corners within
/// 2 sigma (1.6: 89.6%, 1.7: 91.9%).
const LIKELIHOOD_SIGMA_FACTOR: f64 = 1.7;
/// See [`KEEP_MOVE_PX`].
const KEEP_MOVE_SIDE: f64 = 0.02;

/// Each detection verified against its own tag's model ([`verify`]):
/// uncertainties and estimated flags from the fit, corners from it where
/// it moves them far ([`KEEP_MOVE_PX`]), or the detection dropped when the
/// fit contradicts its cells. Detections the fit cannot judge (too small,
/// too hidden) stay as they are.
pub(crate) fn verify_all(
    img: &GrayView<'_>,
    found: Vec<Detection>,
    targets: &[Target],
    p: &DecodingParams,
) -> Vec<Detection> {
    found
        .into_iter()
        .filter_map(|d| verify_one(img, d, targets, p))
        .collect()
}

/// The readings of `last_resort` ([`Decoded::last_resort`]) that lie in
/// no detection of `out` nor hold one, one per tag: of each tag's
/// readings, the best that stands ([`last_resort_stands`]), at most
/// [`LAST_RESORT_TRIES`] of them tried. The tags no look found otherwise,
/// sorted by family and id.
pub(crate) fn last_resorts(
    img: &GrayView<'_>,
    last_resort: Vec<Found>,
    out: &[Detection],
    targets: &[Target],
    p: &DecodingParams,
) -> Vec<Detection> {
    // The readings of each tag no detection holds, grouped as
    // `one_per_tag` keeps one of them; of each group, the best reading
    // that stands once verified. The print is aligned for a faint reading
    // (`unless_faint`) only here, once no other reading has found its tag.
    let mut groups: Vec<Vec<Found>> = Vec::new();
    for f in last_resort {
        let d = &f.reading.det;
        if out.iter().any(|o| same_tag(o, d)) {
            continue;
        }
        match groups
            .iter_mut()
            .find(|g| g.iter().any(|o| same_tag(&o.reading.det, d)))
        {
            Some(g) => g.push(f),
            None => groups.push(vec![f]),
        }
    }
    let mut kept: Vec<Detection> = groups
        .into_iter()
        .filter_map(|mut g| {
            // Best first, as `one_per_tag` picks (`Reading::beats` is a
            // preference, not an order to sort by).
            let mut tries = 0;
            // Readings under glare whose hidden corners only the aligned
            // print confirms, best first: tried after the others.
            let mut confirmed = Vec::new();
            while tries < LAST_RESORT_TRIES && !g.is_empty() {
                let best = (1..g.len()).fold(0, |b, i| {
                    if g[i].reading.beats(&g[b].reading) {
                        i
                    } else {
                        b
                    }
                });
                let d = g.swap_remove(best).reading.det;
                // A reading under glare needs every corner seen, or its
                // hidden ones confirmed; one that has neither is no try.
                if d.glared {
                    match glare_standing(img, &d, targets, p) {
                        Standing::LastResort => {}
                        Standing::PrintConfirmed => {
                            confirmed.push(d);
                            continue;
                        }
                        Standing::Stands | Standing::Falls => continue,
                    }
                }
                tries += 1;
                if let Some(d) = last_resort_stands(img, d, targets, p) {
                    return Some(d);
                }
            }
            confirmed
                .into_iter()
                .take(LAST_RESORT_TRIES)
                .find_map(|d| last_resort_stands(img, d, targets, p))
        })
        .collect();
    kept.sort_by(|a, b| a.family.cmp(&b.family).then(a.id.cmp(&b.id)));
    kept
}

/// Least fixed look of the print ([`print_align::quad_look`], a
/// correlation) of a quad that read to nothing for [`aligned_unread`] to
/// align the print to it. Most quads of clutter look under 0.2, most
/// quads of a tag over 0.5 (see [`print_align::MIN_QUAD_LOOK`]). On the
/// wild set, with the look at least 0.15, 0.3 or 0.45, 54, 52 and 47 more
/// markers were found; 0.3 aligns about a third fewer quads than 0.15.
const UNREAD_MIN_LOOK: f64 = 0.3;

/// Largest cell (px, the data square's side over its cells with the
/// margin, for the family of most cells) of a quad [`aligned_unread`]
/// aligns the print to. Such quads are blurred small tags whose sides
/// refinement measures a pixel or so off, where the cells need corners
/// within half a pixel (decoded at the true corners moved by 1 px, the
/// wild set's missed tags that read at the truth read 76% of the time,
/// against 97% for the tags found), while the aligned print places the
/// square within a few tenths of a pixel. On the wild set's first 1500
/// frames, of the quads of look [`UNREAD_MIN_LOOK`] or more, those of
/// squares under 30 px (cells of 1.9 px on ct14) gave 11 of the 12
/// readings that stood, at 571 of 1343 alignments; those of 30-50 px
/// one reading in 754.
const UNREAD_MAX_CELL_PX: f64 = 1.9;

/// Most quads [`aligned_unread`] aligns the print to in a frame, best
/// look first: each alignment costs about a millisecond. On the wild
/// set's first 1500 frames, 299 had a quad to align, 1 at the median, at
/// most 12, and 4 of them more than 8.
const UNREAD_MAX_ALIGNED: usize = 8;

/// Most quads [`aligned_unread`] aligns the print to around one spot: a
/// quad whose centre lies in this many quads aligned before (and read to
/// nothing) is passed over.
///
/// Why: a tag too blurred or small to read leaves several quads that read
/// nothing, its data square found again with other corners (on the
/// benchmark's cluttered 1080p frames, one such tag had eight, aligned
/// one after the other at 0.6-0.8 ms each, 5 ms of the frame). Why two,
/// not one: on the wild set (3000 frames) one alignment per spot lost 2
/// of the markers found this way (the second quad's alignment read where
/// the first's did not), two lost none and cut the alignments from 1147
/// to 897 (on the benchmark's 1080p frames from 16 to 6; decoding ct14
/// only, from 25 to 10).
const UNREAD_TRIES_PER_SPOT: usize = 2;

/// The quads [`aligned_unread`] has aligned the print to in a frame, for
/// its bounds: [`UNREAD_MAX_ALIGNED`] in all, [`UNREAD_TRIES_PER_SPOT`]
/// around one spot.
#[derive(Debug, Default)]
struct AlignBudget<'u> {
    aligned: Vec<&'u Quad>,
}

impl<'u> AlignBudget<'u> {
    /// Whether the frame's alignments are all made.
    fn spent(&self) -> bool {
        self.aligned.len() >= UNREAD_MAX_ALIGNED
    }

    /// Whether `u` may be aligned, counted as aligned if so.
    fn admits(&mut self, u: &'u Unread) -> bool {
        let here = self.aligned.iter().filter(|q| inside(q, u.centre)).count();
        let ok = !self.spent() && here < UNREAD_TRIES_PER_SPOT;
        if ok {
            self.aligned.push(&u.quad);
        }
        ok
    }
}

/// Whether quad `q` is small enough for [`aligned_unread`]
/// ([`UNREAD_MAX_CELL_PX`]).
fn small_enough_to_align(q: &Quad, targets: &[Target]) -> bool {
    mean_side(q) <= UNREAD_MAX_CELL_PX * most_cells(targets)
}

/// Cells across a data square with its margin ([`MARGIN_CELLS`]) in the
/// target family of most cells: a side over it is the largest cell any
/// target would read there.
fn most_cells(targets: &[Target]) -> f64 {
    targets
        .iter()
        .map(|t| (t.family.grid() + MARGIN_CELLS) as f64)
        .fold(0.0, f64::max)
}

/// The readings of the print aligned ([`print_align::align_quickly`]) to
/// the quads `unread` (see [`Decoded::unread`]) that lie in no tag `out`
/// reports and in no square of a family not decoded (`foreign`), best
/// look first, at most [`UNREAD_MAX_ALIGNED`] of them, none inside a
/// tag read here already and none centred in [`UNREAD_TRIES_PER_SPOT`]
/// quads aligned before: each read as the rim look reads its aligned
/// print, fitted with every corner given a sigma and reported on the
/// aligned corners where the fit agrees ([`on_aligned_print`]), for
/// [`last_resorts`] to judge as it judges every placed reading.
///
/// Why after every look: a quad that reads nothing where refinement put
/// it is most often a tag another quad or look reads, or no tag, and an
/// alignment costs several readings. On the wild set, of the quads left
/// after every look, 91% lay on the data square of a marker no look had
/// found, and their alignment read the right id on a fifth of them.
///
/// Why readings by the nearest codeword, by likelihood at a faint
/// contrast and shaded ones are taken too: on the aligned print their
/// corners are the print's, not the quad's, and the fit and
/// [`last_resorts`]' sigma bounds judge them. On the wild set so, 52
/// more markers (data squares of 16-25 px, every corner within 1 px of
/// the truth), none lost or rough; with the unoccluded, plainly read ones
/// alone, 14.
pub(crate) fn aligned_unread(
    img: &GrayView<'_>,
    unread: &[Unread],
    out: &[Detection],
    foreign: &[Quad],
    targets: &[Target],
    p: &DecodingParams,
) -> Vec<Found> {
    let mut left: Vec<&Unread> = unread
        .iter()
        .filter(|u| !out.iter().any(|d| inside(&d.corners, u.centre)))
        .filter(|u| !foreign.iter().any(|q| inside(q, u.centre)))
        .collect();
    // Stable: equal looks keep the decoding order.
    left.sort_by(|a, b| b.look.total_cmp(&a.look));
    let mut read_here: Vec<Found> = Vec::new();
    let mut budget = AlignBudget::default();
    for u in left {
        if budget.spent() {
            break;
        }
        if read_here
            .iter()
            .any(|f| inside(&f.reading.det.corners, u.centre))
            || !budget.admits(u)
        {
            continue;
        }
        let Some(a) = print_aligned_by(img, &u.quad, print_align::align_quickly) else {
            continue;
        };
        let how = ReadAs {
            shown: shown_grid(img, &a),
            promising: Promising::Smear,
            glared: false,
            rim: false,
        };
        let Some(d) = read(img, &u.estimated, &a, u.centre, targets, &p.decode, how) else {
            continue;
        };
        let Some(t) = target_of(targets, &d) else {
            continue;
        };
        let v = match verify_reading(img, &d, t, p) {
            Verdict::Fitted(v) if v.sigma.iter().all(|s| s.is_finite()) => v,
            _ => continue,
        };
        if let Some(det) = on_aligned_print(d, &v, &a) {
            read_here.push(Found {
                reading: Reading {
                    det,
                    outline: false,
                },
                rivals: 0,
            });
        }
    }
    read_here
}

/// How a reading under glare (`decode::QuadReading::glared`) stands:
/// [`Standing::LastResort`] with every corner seen by the fit of the
/// tag's model, [`Standing::PrintConfirmed`] with its hidden corners where
/// the aligned print puts them too, else it falls (see
/// [`occluded_standing`]). Judged only in [`last_resorts`], where no other
/// reading has found its tag: the fit is the costly part of such a
/// reading, and most are of tags that other quads read.
fn glare_standing(
    img: &GrayView<'_>,
    d: &Detection,
    targets: &[Target],
    p: &DecodingParams,
) -> Standing {
    target_of(targets, d).map_or(Standing::Falls, |t| occluded_standing(img, d, t, p))
}

/// Readings of one tag [`last_resorts`] tries, best first: each costs an
/// alignment of the print and a model fit, and a tag under a glare is
/// read as a last resort from nearly every quad around it (on the wild
/// set a frame's last resorts cost up to 10 ms when all were tried). With
/// 1, 2 or all of them tried, 130, 132 and 133 of the wild set's markers
/// were found as last resorts that are not otherwise.
const LAST_RESORT_TRIES: usize = 2;

/// Last resort `d` as it stands ([`last_resorts`]): unless faint
/// (its print aligned, if its corners are not already the aligned print's),
/// verified, with every estimated corner's sigma within
/// [`LAST_RESORT_SIGMA_PX`], or [`LAST_RESORT_PLACED_SIGMA_PX`] for a
/// placed reading, but [`HIDDEN_FIT_SIGMA_PX`] for the rim look's shaded
/// reading of the aligned print: read through a smooth light field, its
/// cells confirm its geometry less than a code reading's, so its hidden
/// corners must be placed surely enough that twice their sigma is under
/// the 3 px of a rough corner.
fn last_resort_stands(
    img: &GrayView<'_>,
    d: Detection,
    targets: &[Target],
    p: &DecodingParams,
) -> Option<Detection> {
    // The rim look's shaded reading of the aligned print (`rim_attempt`):
    // placed before it gets here, where any other placed reading comes
    // placed out of `unless_faint`.
    let rim_shaded = d.placed && d.last_resort;
    let d = if d.placed {
        d
    } else {
        unless_faint(img, d, targets, p)?
    };
    // An unfitted reading's fit was tried where it was read, on the same
    // corners, and contradicted it: its sigma is its own.
    let d = if d.unfitted {
        d
    } else {
        verify_one(img, d, targets, p)?
    };
    let sigma = d.corner_sigma.unwrap_or([f64::INFINITY; 4]);
    let bound = if rim_shaded {
        HIDDEN_FIT_SIGMA_PX
    } else if d.placed {
        LAST_RESORT_PLACED_SIGMA_PX
    } else {
        LAST_RESORT_SIGMA_PX
    };
    (0..4)
        .all(|k| !d.estimated[k] || sigma[k] <= bound)
        .then_some(d)
}

/// Largest sigma (px) of an estimated corner of a last resort
/// ([`last_resorts`]) once verified: twice it is 2.5 px, under the 3 px of
/// a rough corner. The reading is checked by nothing but its fit and its
/// cells. At [`HIDDEN_FIT_SIGMA_PX`] (1.5 px), a test scene's tag under a
/// grey triangle (`detect_verify::grey_triangles`, 33 px) was kept with a
/// hidden corner 3.1 px off at a sigma of 1.3 px, so the bound stays under
/// 1.3. Against 1.0, where it was first set: 8 more of the wild set's
/// markers (their estimated corners at sigmas of 1.01-1.21 px, at most
/// 1.13 px off), 1 more of the calibration set's, none lost or rough; most
/// glared tags read as last resorts have an estimated corner at 1.3-11 px
/// (up to 3.3 px off), which this leaves out.
const LAST_RESORT_SIGMA_PX: f64 = 1.25;

/// Largest sigma (px) of an estimated corner of a placed last resort
/// (`Detection::placed`: read by the rim look, or faint and confirmed by
/// the aligned print): the 3 px of a rough corner, so that no corner is
/// reported whose own uncertainty is as large as the error the benchmark
/// calls rough. A placed reading's corners are not the fit's measure of
/// the sides: they were placed by the print's whole fixed look or by the
/// fit, and the fit's sigma, which grows with the blur and glare it
/// measured on the edges it saw, bounds them (`verify_one`). Chosen on
/// the calibration set (`make calibrate-sigma`): against 1.25 px, 11 more
/// of its markers, their estimated corners at sigmas up to 2.8 px and
/// at most 1.3 px off, every one within twice its sigma; none lost. On
/// the wild set, 27 more (glared, blurred and occluded tags of 22-48 px
/// read by likelihood), at most 2.5 px off, each estimated corner within
/// twice its sigma, none lost or rough. The unplaced last resorts keep
/// [`LAST_RESORT_SIGMA_PX`]: their corners are the fit's own, and at 2 px
/// one of the wild set's was kept 2 px off at a sigma of 1.4 px.
const LAST_RESORT_PLACED_SIGMA_PX: f64 = 3.0;

/// The verification of each tag found so far ([`verify_all`]), ahead of
/// [`one_per_tag`], on the current thread pool: the fit is a pure function
/// of the image and the reading, and nearly every tag found is one the
/// frame reports, so the fits can run beside other work (the small-tag
/// regions) and be taken up by [`verify_all_par`].
pub(crate) fn verify_ahead(
    img: &GrayView<'_>,
    found: &[Found],
    targets: &[Target],
    p: &DecodingParams,
) -> Vec<Option<Detection>> {
    found
        .par_iter()
        .map(|f| verify_one(img, f.reading.det.clone(), targets, p))
        .collect()
}

/// [`verify_all`] on `workers`' threads, one detection per task (each
/// fit is a pure function of the image and the detection), in the same
/// order, of the detections of [`one_per_tag_indexed`]: those whose
/// reading's index has a fit in `ahead` ([`verify_ahead`]) take it.
pub(crate) fn verify_all_par<W: Default + Send>(
    img: &GrayView<'_>,
    found: Vec<(usize, Detection)>,
    ahead: Vec<Option<Detection>>,
    targets: &[Target],
    p: &DecodingParams,
    workers: &Workers<W>,
) -> Vec<Detection> {
    /// A detection's fit, made ahead, or the detection to fit.
    enum Fit {
        Made(Option<Detection>),
        ToMake(Detection),
    }
    let mut ahead: Vec<Option<Option<Detection>>> = ahead.into_iter().map(Some).collect();
    let fits: Vec<Fit> = found
        .into_iter()
        .map(|(i, d)| match ahead.get_mut(i).and_then(Option::take) {
            Some(made) => Fit::Made(made),
            None => Fit::ToMake(d),
        })
        .collect();
    let kept: Vec<Option<Detection>> = workers.install(|| {
        fits.into_par_iter()
            .map(|f| match f {
                Fit::Made(made) => made,
                Fit::ToMake(d) => verify_one(img, d, targets, p),
            })
            .collect()
    });
    kept.into_iter().flatten().collect()
}

/// One detection of [`verify_all`]: kept (perhaps with new corners), or
/// `None` when dropped.
fn verify_one(
    img: &GrayView<'_>,
    mut d: Detection,
    targets: &[Target],
    p: &DecodingParams,
) -> Option<Detection> {
    let Some(t) = target_of(targets, &d) else {
        return Some(d);
    };
    let verdict = match verify_reading(img, &d, t, p) {
        // A likelihood reading (a small, blurred tag) whose fit keeps its
        // corners stands on its own corners, which read, even when the
        // fitted ones, within a pixel of them, no longer read clearly
        // better than every other id: on such tags the fit, of the sides
        // alone, is the less accurate of the two (this kept 13 readings on
        // the wild set and 11 on the calibration set, every corner within
        // 1.22 px of the truth; their fits were 0.5-1.5 px off). A code
        // reading near the code's limit gets no such leave: one was read
        // through a quad 15 px off that its fit agreed with, and only the
        // fit's failed reading dropped it. But a code reading that would
        // stand without a fit (`stands_unfit`) and whose fit keeps its
        // corners stands on them likewise: small tags read with 5-7
        // corrections whose corners were within 0.1 px of the truth, and
        // whose fit, as close, no longer read within the code's capacity,
        // were dropped (16 on the wild set, every corner within 1.2 px;
        // the reading 15 px off above had 11 corrections).
        Verdict::Contradicted(Some(v))
            if (d.likelihood || stands_unfit(&d, t)) && !moves_corners(&d.corners, &v.corners) =>
        {
            Verdict::Fitted(v)
        }
        v => v,
    };
    match verdict {
        Verdict::Fitted(v) => {
            let mut sigma = v.sigma;
            // A placed reading keeps its corners, the aligned print's or
            // the fit's (`on_aligned_print`, `rim_reading_stands`), the
            // fit's only bound their sigma.
            if moves_corners(&d.corners, &v.corners) && !d.placed {
                d.corners = v.corners;
                d.center = v.homography.map([0.0, 0.0]).unwrap_or(d.center);
                d.homography = v.homography;
            } else {
                // The kept corner is uncertain by the fit's own sigma
                // and by how far the fit puts it.
                for (k, sg) in sigma.iter_mut().enumerate() {
                    *sg = sg.hypot(norm(sub(v.corners[k], d.corners[k])));
                }
            }
            for (e, u) in d.estimated.iter_mut().zip(v.unsupported) {
                *e |= u;
            }
            if d.likelihood {
                for sg in &mut sigma {
                    *sg *= LIKELIHOOD_SIGMA_FACTOR;
                }
            }
            let floors = [
                (d.placed, RIM_SIGMA_OF_SIDE),
                (v.smeared, SMEAR_SIGMA_OF_SIDE),
            ];
            for (_, share) in floors.iter().filter(|(on, _)| *on) {
                let floor = share * mean_side(&d.corners);
                for sg in &mut sigma {
                    *sg = sg.max(floor);
                }
            }
            d.corner_sigma = sigma.iter().all(|s| s.is_finite()).then_some(sigma);
            // A nearest-codeword reading is judged again on the corners it
            // ends with (see `occluded_reading_stands`), and so is any
            // reading of an upsampled small-tag region: such a tag shows
            // little perspective, and its hidden corners, placed by the fit
            // of cells 1-2 px wide, were seen off by more than 3 px (on the
            // sigma calibration set, one of 30 with a hidden corner).
            // Which corners are seen is judged on the fit's geometry, as
            // when the quad was read (the corners kept may differ by up to
            // `KEEP_MOVE_PX`); a nearest-codeword reading's two or more
            // hidden corners stand where the fit places them surely
            // (`hidden_corners_fitted`). Any reading near the code's limit must
            // have its hidden corners where perspective could put them
            // (`hidden_corners_plausible`).
            let hidden = hidden_corners(img, t, &v.corners, d.estimated, v.unsupported);
            let stands =
                occluded_geometry_stands(&d.corners, hidden) || hidden_corners_fitted(&d, hidden);
            let judged = d.occluded || d.upsampled;
            if d.occluded && d.corner_sigma.is_none()
                || judged && !stands
                || !stands_unfit(&d, t) && !hidden_corners_plausible(&d.corners, hidden)
            {
                return None;
            }
            Some(d)
        }
        // A likelihood reading never stands without the fit.
        Verdict::Unfit if stands_unfit(&d, t) => Some(d),
        Verdict::Contradicted(_) if stands_unfit(&d, t) && small_cells(&d, t) => Some(d),
        Verdict::Unfit | Verdict::Contradicted(_) => None,
    }
}

/// Whether reading `d` of target `t` has cells under
/// [`verify::MIN_CELL_EDGE_PX`], too small for the model fit to measure
/// their edges unless a side hides: such a fit stands on the sides, and
/// one that contradicts a reading that stands without a fit
/// ([`stands_unfit`]) leaves it standing, as unfit.
///
/// Why: on a tag this small an occluder's edge beside a side, or a
/// stretch of a side under it, pulls the fit off, and its geometry then
/// reads nothing. On the wild set 9 readings of tags of 19-34 px under
/// occluders, with 0-7 symbols corrected, were dropped so, their fits
/// 1.0-9.5 px off their corners; their corners were right (7 within
/// 0.11 px of the truth, the other two 1.3 px off at a measured corner and
/// 2.1 px at an estimated one). Kept, they add no rough detection and no
/// wrong id on the wild, the calibration or the ct8 sets, nor a false
/// positive. On larger tags the fit, with the cell edges, is the surer of
/// the two, and contradicting still drops the reading.
fn small_cells(d: &Detection, t: &Target) -> bool {
    verify::cell_px(&d.corners, t.family.grid()) < verify::MIN_CELL_EDGE_PX
}

/// Whether reading `d` of target `t` stands when its fit cannot be made:
/// read by the code (a likelihood reading never does) with
/// [`UNFIT_MARGIN`] symbols of the family's limit unused.
fn stands_unfit(d: &Detection, t: &Target) -> bool {
    !d.likelihood && d.corrected + UNFIT_MARGIN <= t.max_corrected
}

/// Whether the fitted corners `fitted` replace a reading's `own` (see
/// [`KEEP_MOVE_PX`]).
fn moves_corners(own: &[[f64; 2]; 4], fitted: &[[f64; 2]; 4]) -> bool {
    let moved = (0..4)
        .map(|k| norm(sub(fitted[k], own[k])))
        .fold(0.0, f64::max);
    moved > KEEP_MOVE_PX.max(KEEP_MOVE_SIDE * mean_side(own))
}

/// Whether reading `a` of a tag is better than reading `b`: a reading by
/// the code over one by likelihood, then fewer Reed-Solomon corrections,
/// then more measured corners. A reading under glare
/// (`decode::QuadReading::glared`) loses to any other: its cells are the
/// fewest seen.
fn better(a: &Detection, b: &Detection) -> bool {
    let real = |d: &Detection| d.estimated.iter().filter(|&&e| !e).count();
    let key = |d: &Detection| {
        (
            !d.glared,
            !d.likelihood,
            std::cmp::Reverse(d.corrected),
            real(d),
        )
    };
    key(a) > key(b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::refine::MIN_EDGE_CONTRAST;

    fn params() -> DecodingParams<'static> {
        DecodingParams {
            max_attempts: 100,
            max_in_vain_run: usize::MAX,
            max_rivals: MAX_RIVALS,
            refine: RefineParams {
                refine: true,
                cells_per_side: 16.0,
                min_edge_contrast: MIN_EDGE_CONTRAST,
            },
            decode: DecodeParams::default(),
            fits: None,
            others: &[],
        }
    }

    /// At most two quads are aligned around one spot and eight in all,
    /// whatever their order: a blurred tag's data square found again and
    /// again is aligned twice, and the other spots still get theirs.
    #[test]
    fn unread_quads_are_aligned_twice_a_spot_and_eight_a_frame() {
        let at = |x: f64, y: f64, d: f64| Unread {
            quad: [
                [x - 10.0 + d, y - 10.0],
                [x - 10.0, y + 10.0 - d],
                [x + 10.0, y + 10.0],
                [x + 10.0, y - 10.0 + d],
            ],
            estimated: [false; 4],
            centre: [x, y],
            look: 0.9,
        };
        // Five quads of one square, corners a pixel or two apart, then
        // one at each of eight other spots.
        let mut quads: Vec<Unread> = (0..5).map(|k| at(50.0, 50.0, k as f64 * 0.5)).collect();
        quads.extend((1..=8).map(|k| at(50.0 + 40.0 * k as f64, 50.0, 0.0)));
        let mut budget = AlignBudget::default();
        let admitted: Vec<bool> = quads.iter().map(|u| budget.admits(u)).collect();
        assert_eq!(admitted[..5], [true, true, false, false, false]);
        // Two at the first spot leave six of the eight for the others.
        assert_eq!(
            admitted[5..],
            [true, true, true, true, true, true, false, false]
        );
        assert!(budget.spent());
        // A quad centred beside (not inside) the two aligned ones is
        // another spot.
        let mut budget = AlignBudget::default();
        assert!(budget.admits(&quads[0]) && budget.admits(&quads[1]));
        assert!(budget.admits(&at(75.0, 50.0, 0.0)));
    }

    /// The aligned print's corners are matched to a reading's under the
    /// quarter turn that brings them nearest, the first of equally near
    /// ones, with the farthest corner's distance under it.
    #[test]
    fn the_aligned_print_is_matched_under_its_nearest_turn() {
        let q = [[10.0, 10.0], [10.0, 30.0], [30.0, 30.0], [30.0, 10.0]];
        for k in 0..4 {
            let mut turned: [[f64; 2]; 4] = std::array::from_fn(|i| q[(i + 4 - k) % 4]);
            turned[(2 + k) % 4][0] += 0.5;
            let (gap, c) = nearest_turn(&turned, &q);
            assert_eq!(gap, 0.5, "turn {k}");
            assert_eq!(c[0], q[0], "turn {k}");
            assert_eq!(c[2], [30.5, 30.0], "turn {k}");
        }
        // A square matched to itself under no turn, not under another
        // as near (a degenerate square, all one point).
        let p = [[5.0, 5.0]; 4];
        assert_eq!(nearest_turn(&p, &p), (0.0, p));
    }

    /// A hidden corner is confirmed where the print, aligned from the
    /// corners, puts it within `GLARE_PRINT_AGREEMENT_PX`, and not where
    /// the corners put it 3 px off the print; no print, a collapsed quad
    /// or NaN corners confirm nothing (and do not panic).
    #[test]
    fn the_aligned_print_confirms_hidden_corners_it_agrees_with() {
        let m = [[36.0, 4.0], [-3.0, 34.0]];
        let (img, truth) = super::print_align::tests::print(m, 1.0);
        let view = GrayView::from(&img);
        assert!(print_agrees_at(&view, &truth, [true; 4]));
        let mut moved = truth;
        moved[2][0] += 3.0;
        let hidden_br = [false, false, true, false];
        assert!(!print_agrees_at(&view, &moved, hidden_br));
        // Where the moved corner is not the hidden one, it is not judged.
        assert!(print_agrees_at(&view, &moved, [true, false, false, false]));
        let blank = image::GrayImage::from_pixel(160, 160, image::Luma([200]));
        assert!(!print_agrees_at(&GrayView::from(&blank), &truth, [true; 4]));
        assert!(!print_agrees_at(&view, &[[80.0, 80.0]; 4], [true; 4]));
        assert!(!print_agrees_at(&view, &[[f64::NAN; 2]; 4], [true; 4]));
    }

    /// A target of `fam` at its default limit.
    fn target(fam: &Family) -> Target {
        Target::of(&FamilySetting::builtin(fam.name()).unwrap())
    }

    /// The rim look leaves a family unread only on squares where none of
    /// its readings could stand: ct14's need cells of 1.5 px over 16 (24
    /// px), ct8's over 10 (15 px). A print aligned at the limit, or moved
    /// to 0.975 of it (`ALIGNED_JITTER`), is read.
    #[test]
    fn rim_squares_too_small_for_a_family_are_not_read_as_it() {
        let square = |s: f64| {
            [
                [10.0, 10.0],
                [10.0, 10.0 + s],
                [10.0 + s, 10.0 + s],
                [10.0 + s, 10.0],
            ]
        };
        let (ct8, ct14) = (target(Family::ct8()), target(Family::ct14()));
        assert!(too_small_for_rim(&square(20.0), &ct14));
        assert!(!too_small_for_rim(&square(20.0), &ct8));
        assert!(too_small_for_rim(&square(13.0), &ct8));
        for (t, limit) in [(&ct14, 24.0), (&ct8, 15.0)] {
            for k in [1.0, 0.975] {
                assert!(!too_small_for_rim(&square(k * limit), t));
                // And a pixel-wide tilt of one side does not tip it.
                let mut q = square(k * limit);
                q[2][0] -= 1.0;
                assert!(!too_small_for_rim(&q, t));
            }
        }
    }

    /// A tag of a built-in family the detector does not decode reads as
    /// that family's, for a detector of either family alone; a tag of a
    /// family decoded, a blank square and degenerate quads do not.
    #[test]
    fn a_square_of_a_family_not_looked_for_reads_as_foreign() {
        let (ct8, ct14) = (Family::ct8(), Family::ct14());
        // The families not decoded by a ct14-only detector, a ct8-only
        // one, and one of both.
        let (not8, not14, none) = ([target(ct8)], [target(ct14)], []);
        let undecoded = |others| DecodingParams { others, ..params() };
        let (only14, only8, both) = (undecoded(&not8), undecoded(&not14), undecoded(&none));
        for (k, side) in [26.0, 40.0, 90.0].into_iter().enumerate() {
            let turn = 0.3 * k as f64;
            let (img, q) =
                crate::test_images::family_tag_image(ct8, 4321, side, [160.0, 160.0], turn);
            let img = GrayView::from(&img);
            assert!(reads_as_other_family(&img, &q, &only14), "{side}");
            // With its family decoded, it is not.
            assert!(!reads_as_other_family(&img, &q, &only8), "{side}");
            assert!(!reads_as_other_family(&img, &q, &both), "{side}");
            // A ct14 tag is no ct8 one, and the other way round.
            let (img, q) =
                crate::test_images::family_tag_image(ct14, 77, side, [160.0, 160.0], turn);
            let img = GrayView::from(&img);
            assert!(!reads_as_other_family(&img, &q, &only14), "{side}");
            assert!(reads_as_other_family(&img, &q, &only8), "{side}");
        }
        // Nor is a blank square, a square partly off the image, or three
        // corners on a line, as either family.
        let img = image::GrayImage::from_pixel(320, 320, image::Luma([128]));
        let img = GrayView::from(&img);
        let neither = [target(ct8), target(ct14)];
        for q in [
            square([160.0, 160.0], 40.0),
            square([5.0, 5.0], 40.0),
            [[10.0, 10.0], [20.0, 20.0], [30.0, 30.0], [40.0, 10.0]],
        ] {
            assert!(
                !reads_as_other_family(&img, &q, &undecoded(&neither)),
                "{q:?}"
            );
        }
    }

    /// A disc rim (working px at `scale` 1) as the rim look measures it
    /// around a data square of side `side` centred on `c`: a circle, its
    /// border points half a pixel inside the edge.
    fn rim_around(c: [f64; 2], side: f64) -> super::super::ellipses::Ellipse {
        let r = rim::RIM_RADIUS * side - 0.5;
        super::super::ellipses::Ellipse {
            centre: c,
            a: r,
            b: r,
            anchor: c,
            checker: false,
            axis: [1.0, 0.0],
            pieced: false,
        }
    }

    #[test]
    fn an_unfitted_reading_on_the_aligned_print_stands_only_as_a_last_resort() {
        let (c, side) = ([100.0, 100.0], 40.0);
        let d = Detection {
            center: c,
            ..found(square(c, side), 9).reading.det
        };
        let t = [target(Family::ct14())];
        // Where the rim agrees, every corner is estimated, at a sigma of a
        // share of the side.
        let u = unfitted_on_aligned(d.clone(), &t, &rim_around(c, side), 1.0).unwrap();
        assert!(u.unfitted && u.placed && u.estimated == [true; 4]);
        assert_eq!(u.corners, d.corners);
        let sigma = u.corner_sigma.unwrap();
        assert!(sigma
            .iter()
            .all(|&s| (s - UNFITTED_SIGMA_OF_SIDE * side).abs() < 1e-9));
        // A rim a third larger, or off by a third of the side, disagrees;
        // a square under the smallest rim reading's cells is refused.
        assert!(unfitted_on_aligned(d.clone(), &t, &rim_around(c, side * 1.33), 1.0).is_none());
        let off = [c[0] + side / 3.0, c[1]];
        assert!(unfitted_on_aligned(d.clone(), &t, &rim_around(off, side), 1.0).is_none());
        let tiny = found(square(c, 20.0), 9).reading.det;
        assert!(unfitted_on_aligned(tiny, &t, &rim_around(c, 20.0), 1.0).is_none());
        // As a last resort it stands on its own sigma, with no fit (on a
        // blank image, where a fit would find nothing), unless a
        // detection of the same tag was made.
        let img = image::GrayImage::from_pixel(200, 200, image::Luma([128]));
        let img = GrayView::from(&img);
        let last = |out: &[Detection]| {
            let r = Found {
                reading: Reading {
                    det: u.clone(),
                    outline: false,
                },
                rivals: 0,
            };
            last_resorts(&img, vec![r], out, &t, &params())
        };
        assert_eq!(last(&[]), vec![u.clone()]);
        assert!(last(&[d]).is_empty());
        // A reading that is not unfitted goes through the fit, and on the
        // blank image falls.
        let fitted = Detection {
            unfitted: false,
            ..u.clone()
        };
        assert!(last_resort_stands(&img, fitted, &t, &params()).is_none());
    }

    /// A fit made once in a frame is taken again from the frame's `Fits`
    /// for the same reading on the same image, as it was made; a reading
    /// that differs in any input (a corner moved by a bit, another image)
    /// is fitted afresh.
    #[test]
    fn a_fit_is_made_once_per_frame_and_reading() {
        let (img, q) = crate::test_images::tag_image(42, 80.0, [160.0, 160.0], 0.3);
        let (img2, _) = crate::test_images::tag_image(43, 80.0, [160.0, 160.0], 0.3);
        let (img, img2) = (GrayView::from(&img), GrayView::from(&img2));
        let t = target(Family::ct14());
        let d = found(q, 1).reading.det;
        let fits = Fits::default();
        let memo = DecodingParams {
            fits: Some(&fits),
            ..params()
        };
        let made = |img: &GrayView<'_>, d: &Detection, p: &DecodingParams| {
            format!("{:?}", verify_reading(img, d, &t, p))
        };
        let count = || fits.0.lock().unwrap().len();
        let plain = made(&img, &d, &params());
        assert!(plain.starts_with("Fitted"), "{plain}");
        assert_eq!(made(&img, &d, &memo), plain);
        assert_eq!(made(&img, &d, &memo), plain);
        assert_eq!(count(), 1);
        // A corner moved by the last bit of its mantissa.
        let mut moved = d.clone();
        moved.corners[2][0] = f64::from_bits(moved.corners[2][0].to_bits() + 1);
        assert_eq!(made(&img, &moved, &memo), made(&img, &moved, &params()));
        assert_eq!(count(), 2);
        // Another tag's image: its fit contradicts the reading, as made.
        let other = made(&img2, &d, &memo);
        assert_eq!(other, made(&img2, &d, &params()));
        assert!(other.starts_with("Contradicted"), "{other}");
        assert_eq!(count(), 3);
    }

    /// An axis-aligned square of side `side` centred on `c`, anticlockwise
    /// on screen.
    fn square(c: [f64; 2], side: f64) -> [[f64; 2]; 4] {
        let h = side / 2.0;
        [
            [c[0] - h, c[1] - h],
            [c[0] - h, c[1] + h],
            [c[0] + h, c[1] + h],
            [c[0] + h, c[1] - h],
        ]
    }

    /// A tag read with `corrected` corrections over `corners`.
    fn found(corners: [[f64; 2]; 4], corrected: usize) -> Found {
        Found {
            reading: Reading {
                det: Detection {
                    family: "ct14".to_string(),
                    id: 42,
                    corners,
                    estimated: [false; 4],
                    corner_sigma: None,
                    corrected,
                    likelihood: false,
                    occluded: false,
                    upsampled: false,
                    placed: false,
                    faint: false,
                    last_resort: false,
                    glared: false,
                    unfitted: false,
                    center: [0.0, 0.0],
                    contrast: 200.0,
                    homography: Homography::from_points(&CORNERS, &corners).unwrap(),
                },
                outline: false,
            },
            rivals: 0,
        }
    }

    /// A candidate over `corners` (full resolution) in a working image
    /// `scale` times smaller.
    fn candidate(corners: [[f64; 2]; 4], scale: f64) -> Candidate {
        let corners = corners.map(|q| [(q[0] + 0.5) / scale - 0.5, (q[1] + 0.5) / scale - 0.5]);
        Candidate {
            corners,
            estimated: [false; 4],
            edges: [None; 4],
            anchor: None,
            real: 4,
            area: mean_side(&corners).powi(2),
            linked: false,
            guessed: false,
            rim: None,
        }
    }

    #[test]
    fn a_reading_kept_with_a_last_resort_hands_on_both() {
        let p = params();
        let (a, b) = (square([100.0, 100.0], 40.0), square([300.0, 100.0], 40.0));
        let cands = [candidate(a, 1.0), candidate(b, 1.0)];
        let reading = |q| {
            Box::new(Reading {
                det: Detection {
                    center: centroid(&q),
                    ..found(q, 3).reading.det
                },
                outline: false,
            })
        };
        let out = decode_in_order(
            &cands,
            1.0,
            &p,
            |j, _| match j {
                0 => Outcome::ReadKeeping(reading(a), reading(a)),
                _ => Outcome::LastResort(reading(b)),
            },
            |_, _, _| {},
        );
        // The reading is found, its fallback and the other candidate's
        // reading wait as last resorts; both count as decoded.
        assert_eq!(out.found.len(), 1);
        assert_eq!(out.found[0].detection().corners, a);
        let last: Vec<_> = out
            .last_resort
            .iter()
            .map(|f| f.detection().corners)
            .collect();
        assert_eq!(last, vec![a, b]);
        assert_eq!(out.attempts, 2);
    }

    #[test]
    fn rivals_within_the_cells_are_dismissed_unread() {
        let p = params();
        let tag = [found(square([500.0, 400.0], 270.0), 5)];
        let plan_of = |corners, scale| {
            let c = candidate(corners, scale);
            plan(&c, centre_of(&c, scale), scale, &tag, &[], &p)
        };
        for scale in [1.0, 2.0] {
            // A cell (a sixteenth of the side) and the centre checker (a
            // quarter) cannot be the tag's data square.
            assert_eq!(
                plan_of(square([540.0, 430.0], 17.0), scale),
                Plan::Dismiss(0)
            );
            assert_eq!(
                plan_of(square([500.0, 400.0], 68.0), scale),
                Plan::Dismiss(0)
            );
            // The data square cut in two by a stick, and the whole square
            // through a false corner, may be.
            let half = [
                [365.0, 265.0],
                [365.0, 400.0],
                [635.0, 400.0],
                [635.0, 265.0],
            ];
            assert_eq!(plan_of(half, scale), Plan::Decode(Some(0)));
            let mut moved = square([500.0, 400.0], 270.0);
            moved[2] = [620.0, 520.0];
            assert_eq!(plan_of(moved, scale), Plan::Decode(Some(0)));
            // Outside the tag, any size is a new candidate.
            assert_eq!(
                plan_of(square([900.0, 400.0], 17.0), scale),
                Plan::Decode(None)
            );
        }
        // A tag read cleanly has no rivals at all, small or not.
        let clean = [found(square([500.0, 400.0], 270.0), 0)];
        let c = candidate(square([540.0, 430.0], 17.0), 1.0);
        assert_eq!(
            plan(&c, centre_of(&c, 1.0), 1.0, &clean, &[], &p),
            Plan::Skip
        );
        // A dismissed rival counts against the tag's rivals: once they are
        // used up, the next one is skipped.
        let mut used = [found(square([500.0, 400.0], 270.0), 5)];
        used[0].rivals = MAX_RIVALS;
        let c = candidate(square([540.0, 430.0], 17.0), 1.0);
        assert_eq!(
            plan(&c, centre_of(&c, 1.0), 1.0, &used, &[], &p),
            Plan::Skip
        );
    }

    #[test]
    fn candidates_over_another_familys_square_are_skipped() {
        let p = params();
        let foreign = [square([500.0, 400.0], 100.0)];
        // The square's outline and a piece of it: skipped.
        for corners in [square([500.0, 400.0], 200.0), square([480.0, 420.0], 40.0)] {
            let c = candidate(corners, 1.0);
            assert_eq!(
                plan(&c, centre_of(&c, 1.0), 1.0, &[], &foreign, &p),
                Plan::Skip
            );
        }
        // Beside it: a candidate as any other.
        let c = candidate(square([700.0, 400.0], 100.0), 1.0);
        assert_eq!(
            plan(&c, centre_of(&c, 1.0), 1.0, &[], &foreign, &p),
            Plan::Decode(None)
        );
        // Inside a tag found, a rival as before.
        let tag = [found(square([500.0, 400.0], 270.0), 5)];
        let c = candidate(square([500.0, 400.0], 200.0), 1.0);
        assert_eq!(
            plan(&c, centre_of(&c, 1.0), 1.0, &tag, &foreign, &p),
            Plan::Decode(Some(0))
        );
    }
}
