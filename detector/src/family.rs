//! Tag families as values.
//!
//! A [`Family`] holds every fact a generator, a renderer and a decoder must
//! agree on: grid size, id range, Reed-Solomon parameters, the cell order of
//! the bitstream, the covered centre cells and the verify symbols. The two
//! built-in families, `ct14` and `ct8`, are read from `data/families.json`,
//! a copy of the format contract (`spec/families.json`), so the code has one
//! source of truth and a new family (for example an RS(20,4) variant of ct14)
//! is a new JSON entry or a [`FamilySpec`] built in code, not new constants.

use std::collections::HashMap;
use std::sync::{Arc, OnceLock};

use serde::{Deserialize, Serialize};

use crate::grid_code::{mask, rotate_cell};
use crate::likelihood::Codebook;
use crate::rs::ReedSolomon;
use crate::{Error, Result};

/// The family definitions shipped with the crate (a copy of the format
/// contract's `families.json`).
const BUILTIN_JSON: &str = include_str!("../data/families.json");

/// Reed-Solomon parameters of a family, as written in `families.json`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RsSpec {
    /// Bits per symbol, m (the field is GF(2^m)).
    pub symbol_bits: u32,
    /// Primitive polynomial of the field, with the x^m term (0x187 for ct14).
    pub primitive_poly: u32,
    /// Exponent of the first consecutive root of the generator polynomial.
    pub first_root: u32,
    /// Parity symbols, n - k.
    pub parity: usize,
    /// Transmitted codeword length in symbols.
    pub n: usize,
    /// Data symbols per codeword.
    pub k: usize,
    /// Length of the unshortened code (2^m - 1); informational.
    #[serde(default)]
    pub shortened_from: Option<usize>,
}

/// A family definition as data: the serialised form of [`Family`].
///
/// Field meanings are those of the format contract
/// (`coppertag-format.md`). Validate and turn it into a usable family with
/// [`Family::from_spec`].
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct FamilySpec {
    /// Family name, for example `ct14`.
    pub name: String,
    /// Side of the data grid in cells, n.
    pub grid: usize,
    /// Inclusive id range `[min, max]`.
    pub ids: [u64; 2],
    /// Reed-Solomon code.
    pub rs: RsSpec,
    /// Human-readable description of the data symbols; informational.
    #[serde(default)]
    pub data_symbols: String,
    /// Verify symbols a decoder accepts.
    pub verify_symbols: Vec<u8>,
    /// Bits written into the grid (codeword bits plus zero padding).
    pub bitstream_bits: usize,
    /// Bit k of the stream goes to cell `cell_order[k]`.
    pub cell_order: Vec<u16>,
    /// Cells under the centre checker; they carry no information.
    pub covered_cells: Vec<u16>,
    /// Side of the centre checker in cells.
    pub center_checker_cells: usize,
    /// Verify symbol of every id not in `verify_exceptions`.
    pub verify_default: u8,
    /// `(id, verify)` pairs that differ from `verify_default`.
    pub verify_exceptions: Vec<(u64, u8)>,
}

#[derive(Deserialize)]
struct FamilyFile {
    families: Vec<FamilySpec>,
}

/// Default most corrections accepted on a ct8 reading: 3 of the 5 its
/// RS(15,5) code corrects. ct8's short code is the weak point for false
/// reads in clutter. Read at their true corners ([`crate::decode_quad`])
/// with the full capacity, 3 of the 2002 markers of the wild scenes with
/// ct8 tags (`datasets/wild/coppertag-wild.toml` with `family = "ct8"`,
/// every third scene) read as another id, with 5-7 symbols corrected,
/// among the 383 read with more than 3. ct14 keeps all 9 of its RS(20,2).
pub const CT8_MAX_CORRECTED: usize = 3;

/// A validated tag family: the one value generator, renderer and decoder
/// share.
#[derive(Debug, Clone)]
pub struct Family {
    spec: FamilySpec,
    code: ReedSolomon,
    exceptions: HashMap<u64, u8>,
    /// `cell_order[k]` for the code bits only, as `usize` for indexing.
    code_cells: Vec<usize>,
    /// Per quarter turn `d`, where each code bit's cell is seen
    /// ([`rotate_cell`]) and its mask bit ([`mask`]): the decoder reads
    /// the grid at four rotations for every quad, and computing the two
    /// per bit (divisions by the grid side) took half its time.
    seen_code_cells: [Vec<(usize, bool)>; 4],
    covered: Vec<bool>,
    /// Every codeword as a blurred tag shows it, for the likelihood
    /// reading of blurred tags; built on first use (about 6 ms for ct14)
    /// and shared by the family's clones. Holds `None` for a family with too
    /// many codewords for that reading.
    codebook: Arc<OnceLock<Option<Codebook>>>,
}

impl Family {
    /// Validates a family definition.
    ///
    /// Checks that the RS code exists, that the cell order is a permutation
    /// of the grid, that the codeword fits the bitstream, that the id range
    /// fits the data symbols and that the verify symbols fit one symbol.
    pub fn from_spec(spec: FamilySpec) -> Result<Self> {
        let bad = |reason: String| Error::InvalidFamily {
            family: spec.name.clone(),
            reason,
        };
        let rs = &spec.rs;
        if rs.parity != rs.n.saturating_sub(rs.k) {
            return Err(bad(format!(
                "parity {} is not n - k = {} - {}",
                rs.parity, rs.n, rs.k
            )));
        }
        let code = ReedSolomon::new(rs.symbol_bits, rs.primitive_poly, rs.first_root, rs.n, rs.k)?;
        let n = spec.grid;
        if !(2..=64).contains(&n) {
            return Err(bad(format!("grid {n} is outside 2..=64")));
        }
        let cells = n * n;
        if spec.bitstream_bits != cells || spec.cell_order.len() != cells {
            return Err(bad(format!(
                "bitstream_bits {} and cell_order length {} must both equal grid^2 = {cells}",
                spec.bitstream_bits,
                spec.cell_order.len()
            )));
        }
        let mut seen = vec![false; cells];
        for &c in &spec.cell_order {
            let c = usize::from(c);
            if c >= cells || seen[c] {
                return Err(bad(format!("cell_order is not a permutation (cell {c})")));
            }
            seen[c] = true;
        }
        let code_bits = rs.n * rs.symbol_bits as usize;
        if code_bits > cells {
            return Err(bad(format!(
                "{code_bits} code bits do not fit {cells} cells"
            )));
        }
        if rs.k < 2 {
            return Err(bad(
                "k must hold at least one id symbol and the verify symbol".into(),
            ));
        }
        let id_bits = (rs.k - 1) * rs.symbol_bits as usize;
        let [min, max] = spec.ids;
        if min > max || (id_bits < 64 && max >= 1u64 << id_bits) {
            return Err(bad(format!(
                "id range {min}..={max} does not fit {id_bits} bits"
            )));
        }
        let sym_max = (1u32 << rs.symbol_bits) - 1;
        let symbol_fits = |v: u8| u32::from(v) <= sym_max;
        if spec.verify_symbols.is_empty() || !spec.verify_symbols.iter().all(|&v| symbol_fits(v)) {
            return Err(bad("verify_symbols must be non-empty symbols".into()));
        }
        let mut exceptions = HashMap::with_capacity(spec.verify_exceptions.len());
        for &(id, v) in &spec.verify_exceptions {
            if id < min || id > max || !spec.verify_symbols.contains(&v) {
                return Err(bad(format!("verify exception ({id}, {v}) is invalid")));
            }
            exceptions.insert(id, v);
        }
        if !spec.verify_symbols.contains(&spec.verify_default) {
            return Err(bad("verify_default is not a verify symbol".into()));
        }
        let mut covered = vec![false; cells];
        for &c in &spec.covered_cells {
            let c = usize::from(c);
            if c >= cells {
                return Err(bad(format!("covered cell {c} is outside the grid")));
            }
            covered[c] = true;
        }
        if spec.center_checker_cells == 0 || spec.center_checker_cells > n {
            return Err(bad("center_checker_cells must be in 1..=grid".into()));
        }
        let code_cells: Vec<usize> = spec.cell_order[..code_bits]
            .iter()
            .map(|&c| usize::from(c))
            .collect();
        let seen_code_cells = std::array::from_fn(|d| {
            code_cells
                .iter()
                .map(|&c| (rotate_cell(c, n, d), mask(c, n)))
                .collect()
        });
        Ok(Self {
            spec,
            code,
            exceptions,
            code_cells,
            seen_code_cells,
            covered,
            codebook: Arc::default(),
        })
    }

    /// The family's codebook for the likelihood reading
    /// ([`crate::likelihood`]), built on first use ([`crate::Detector::new`]
    /// uses it first, so that no frame waits for it); `None` when the
    /// family has too many codewords.
    pub(crate) fn codebook(&self) -> Option<&Codebook> {
        self.codebook.get_or_init(|| Codebook::new(self)).as_ref()
    }

    /// Parses every family of a `families.json` document.
    pub fn parse_json(json: &str) -> Result<Vec<Self>> {
        let file: FamilyFile = serde_json::from_str(json).map_err(|e| Error::InvalidFamily {
            family: "<json>".into(),
            reason: e.to_string(),
        })?;
        file.families.into_iter().map(Self::from_spec).collect()
    }

    /// The built-in families, `ct14` then `ct8`.
    pub fn builtin() -> &'static [Family] {
        static FAMILIES: OnceLock<Vec<Family>> = OnceLock::new();
        FAMILIES.get_or_init(|| {
            // The JSON is compiled in and checked by the tests: failure here
            // is a build defect, not user input.
            Self::parse_json(BUILTIN_JSON).expect("built-in families.json is valid")
        })
    }

    /// A built-in family by name (`ct14`, `ct8`).
    pub fn by_name(name: &str) -> Result<&'static Family> {
        let all = Self::builtin();
        all.iter()
            .find(|f| f.name() == name)
            .ok_or_else(|| Error::UnknownFamily {
                name: name.to_string(),
                known: all.iter().map(|f| f.name()).collect::<Vec<_>>().join(", "),
            })
    }

    /// The ct14 family: 14 x 14 grid, RS(20,2) over GF(256), ids 0..=255.
    pub fn ct14() -> &'static Family {
        Self::by_name("ct14").expect("ct14 is built in")
    }

    /// The ct8 family: 8 x 8 grid, RS(15,5) over GF(16), ids 0..=65535.
    pub fn ct8() -> &'static Family {
        Self::by_name("ct8").expect("ct8 is built in")
    }

    /// The definition this family was built from.
    pub fn spec(&self) -> &FamilySpec {
        &self.spec
    }

    /// Family name.
    pub fn name(&self) -> &str {
        &self.spec.name
    }

    /// Most Reed-Solomon symbols a reading of this family is trusted to
    /// correct unless told otherwise: [`CT8_MAX_CORRECTED`] for the
    /// built-in ct8, the code's capacity for any other family.
    pub fn default_correction_limit(&self) -> usize {
        let cap = self.code().correctable();
        match Family::by_name("ct8") {
            Ok(ct8) if ct8 == self => CT8_MAX_CORRECTED.min(cap),
            _ => cap,
        }
    }

    /// Side of the data grid in cells.
    pub fn grid(&self) -> usize {
        self.spec.grid
    }

    /// Number of cells, grid^2.
    pub fn cells(&self) -> usize {
        self.spec.grid * self.spec.grid
    }

    /// Smallest valid id.
    pub fn min_id(&self) -> u64 {
        self.spec.ids[0]
    }

    /// Largest valid id.
    pub fn max_id(&self) -> u64 {
        self.spec.ids[1]
    }

    /// The family's Reed-Solomon code.
    pub fn code(&self) -> &ReedSolomon {
        &self.code
    }

    /// Side of the centre checker in cells.
    pub fn checker_cells(&self) -> usize {
        self.spec.center_checker_cells
    }

    /// Whether a cell lies under the centre checker (and so carries nothing
    /// a decoder can read).
    pub fn is_covered(&self, cell: usize) -> bool {
        self.covered.get(cell).copied().unwrap_or(false)
    }

    /// Cells that carry code bits, in bitstream order: code bit k lives in
    /// `code_cells()[k]`.
    pub fn code_cells(&self) -> &[usize] {
        &self.code_cells
    }

    /// Per code bit, in bitstream order, the cell it is seen in at `d`
    /// quarter turns and its mask bit.
    pub(crate) fn seen_code_cells(&self, d: usize) -> &[(usize, bool)] {
        &self.seen_code_cells[d % 4]
    }

    /// Checks an id against the family's range.
    pub fn check_id(&self, id: u64) -> Result<()> {
        if id < self.min_id() || id > self.max_id() {
            return Err(Error::IdOutOfRange {
                family: self.name().to_string(),
                id,
                min: self.min_id(),
                max: self.max_id(),
            });
        }
        Ok(())
    }

    /// The verify symbol the reference generator uses for `id`.
    pub fn verify_symbol(&self, id: u64) -> u8 {
        self.exceptions
            .get(&id)
            .copied()
            .unwrap_or(self.spec.verify_default)
    }

    /// Whether `v` is one of the family's verify symbols.
    pub fn is_verify_symbol(&self, v: u8) -> bool {
        self.spec.verify_symbols.contains(&v)
    }

    /// The data symbols of an id: the id in base 2^m, least significant
    /// symbol first, then the verify symbol. This is the one rule behind both
    /// `[id, verify]` (ct14) and the four nibbles of ct8.
    pub fn data_symbols(&self, id: u64) -> Result<Vec<u8>> {
        self.check_id(id)?;
        let m = self.code.symbol_bits();
        let mask = (1u64 << m) - 1;
        let mut data: Vec<u8> = (0..self.code.k() - 1)
            .map(|i| ((id >> (i as u32 * m)) & mask) as u8)
            .collect();
        data.push(self.verify_symbol(id));
        Ok(data)
    }

    /// Reads the id and verify symbol back from data symbols (inverse of
    /// [`Family::data_symbols`]), or `None` when the id is out of range.
    pub fn id_from_data(&self, data: &[u8]) -> Option<(u64, u8)> {
        let k = self.code.k();
        if data.len() < k {
            return None;
        }
        let m = self.code.symbol_bits();
        let id = data[..k - 1]
            .iter()
            .enumerate()
            .fold(0u64, |acc, (i, &s)| acc | (u64::from(s) << (i as u32 * m)));
        (id >= self.min_id() && id <= self.max_id()).then_some((id, data[k - 1]))
    }
}

/// Two families are equal when their definitions are.
impl PartialEq for Family {
    fn eq(&self, other: &Self) -> bool {
        self.spec == other.spec
    }
}

/// A family serialises as its name when it is the built-in family of that
/// name, else as its whole definition ([`FamilySpec`]); both forms
/// deserialise (a name must be a built-in family's, a definition is
/// validated with [`Family::from_spec`]). Run logs stay short and any
/// family a detector was configured with can be rebuilt from them.
impl Serialize for Family {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match Family::by_name(self.name()) {
            Ok(b) if b.spec == self.spec => s.serialize_str(self.name()),
            _ => self.spec.serialize(s),
        }
    }
}

impl<'de> Deserialize<'de> for Family {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Form {
            Name(String),
            Spec(Box<FamilySpec>),
        }
        let family = match Form::deserialize(d)? {
            Form::Name(n) => Family::by_name(&n).cloned(),
            Form::Spec(spec) => Family::from_spec(*spec),
        };
        family.map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_families_load() {
        let ct14 = Family::ct14();
        assert_eq!(ct14.grid(), 14);
        assert_eq!(ct14.code().n(), 20);
        assert_eq!(ct14.code_cells().len(), 160);
        assert_eq!(ct14.max_id(), 255);
        let ct8 = Family::ct8();
        assert_eq!(ct8.code_cells().len(), 60);
        assert_eq!(ct8.max_id(), 65535);
        assert_eq!(ct8.verify_symbol(3), 1);
        assert_eq!(ct8.verify_symbol(4), 0);
    }

    #[test]
    fn a_detector_builds_its_families_codebooks() {
        // A family of its own (a fresh codebook cell, not the built-in
        // ct14's, which other tests may have built), cloned into the
        // detector's settings: the clones share the cell.
        let own = Family::from_spec(Family::ct14().spec().clone()).unwrap();
        assert!(own.codebook.get().is_none());
        let config = crate::DetectorConfig {
            families: vec![crate::FamilySetting::new(own.clone())],
            ..crate::DetectorConfig::default()
        };
        crate::Detector::new(config).unwrap();
        assert!(own.codebook.get().is_some_and(Option::is_some));
    }

    #[test]
    fn data_symbols_match_the_spec() {
        assert_eq!(Family::ct14().data_symbols(42).unwrap(), vec![42, 0]);
        assert_eq!(Family::ct14().data_symbols(35).unwrap(), vec![35, 1]);
        assert_eq!(
            Family::ct8().data_symbols(0x1234).unwrap(),
            vec![4, 3, 2, 1, 0]
        );
        assert_eq!(
            Family::ct8().id_from_data(&[4, 3, 2, 1, 0]),
            Some((0x1234, 0))
        );
    }

    #[test]
    fn unknown_family_and_bad_id_are_errors() {
        assert!(matches!(
            Family::by_name("ct99"),
            Err(Error::UnknownFamily { .. })
        ));
        assert!(matches!(
            Family::ct14().data_symbols(256),
            Err(Error::IdOutOfRange { .. })
        ));
    }

    #[test]
    fn a_new_family_is_a_spec() {
        // The paper's RS(20,4) variant of ct14: three id symbols, 24-bit ids.
        let mut spec = Family::ct14().spec().clone();
        spec.name = "ct14rs204".into();
        spec.rs.k = 4;
        spec.rs.parity = 16;
        spec.ids = [0, (1 << 24) - 1];
        spec.verify_exceptions.clear();
        let fam = Family::from_spec(spec).unwrap();
        assert_eq!(fam.data_symbols(0x010203).unwrap(), vec![3, 2, 1, 0]);
    }

    #[test]
    fn inconsistent_specs_are_rejected() {
        let mut spec = Family::ct8().spec().clone();
        spec.cell_order[1] = spec.cell_order[0];
        assert!(matches!(
            Family::from_spec(spec),
            Err(Error::InvalidFamily { .. })
        ));
        let mut spec = Family::ct8().spec().clone();
        spec.ids = [0, 1 << 20];
        assert!(Family::from_spec(spec).is_err());
    }
}
