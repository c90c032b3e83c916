//! Positions in TOML input files (dataset specs, occlusion patterns) for
//! error messages of the form `file:line:col: message`.
//!
//! Syntax and type errors carry the parser's own span
//! ([`toml::de::Error::span`]). Value errors found after deserialising (a
//! negative size, a marker behind the camera) are placed with
//! [`KeyLocator`], which walks the parser's spanned document tree
//! ([`toml::de::DeTable`]) to the key that holds the value, so the position
//! is the parser's, not a text search.

use std::ops::Range;
use std::path::Path;

use toml::de::{DeTable, DeValue};
use toml::Spanned;

use crate::error::SynthError;

/// Line and column (from 1) of a byte offset.
#[must_use]
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// An input error at byte `offset` of `text`.
#[must_use]
pub fn error_at(path: &Path, text: &str, offset: usize, message: String) -> SynthError {
    let (line, column) = line_col(text, offset);
    SynthError::Input {
        path: path.to_path_buf(),
        line,
        column,
        message,
    }
}

/// A TOML parse or type error as a [`SynthError::Input`] with position.
#[must_use]
pub fn toml_error(path: &Path, text: &str, e: &toml::de::Error) -> SynthError {
    let offset = e.span().map_or(0, |s| s.start);
    error_at(path, text, offset, e.message().trim().to_string())
}

/// One step of a key path: a table key or an array element.
#[derive(Debug, Clone, Copy)]
pub enum Step<'a> {
    /// A key of a table.
    Key(&'a str),
    /// An element of an array (also of an array of tables, `[[markers]]`).
    Index(usize),
}

impl<'a> From<&'a str> for Step<'a> {
    fn from(k: &'a str) -> Self {
        Step::Key(k)
    }
}

impl From<usize> for Step<'_> {
    fn from(i: usize) -> Self {
        Step::Index(i)
    }
}

/// Finds where keys are in a TOML document, from the parser's spans.
pub struct KeyLocator<'a> {
    path: &'a Path,
    text: &'a str,
    root: Option<Spanned<DeTable<'a>>>,
}

impl<'a> KeyLocator<'a> {
    /// Parses `text` (already known to be valid TOML: it was deserialised).
    #[must_use]
    pub fn new(path: &'a Path, text: &'a str) -> Self {
        Self {
            path,
            text,
            root: DeTable::parse(text).ok(),
        }
    }

    /// The span of the deepest step of `steps` that exists: the key itself
    /// for a table key, the element for an array element; the start of the
    /// file when not even the first step exists (a default value).
    fn span(&self, steps: &[Step]) -> Range<usize> {
        let Some(root) = &self.root else {
            return 0..0;
        };
        let mut best = 0..0;
        let mut table: Option<&DeTable> = Some(root.get_ref());
        let mut value: Option<&Spanned<DeValue>> = None;
        for step in steps {
            let next = match (*step, table, value) {
                (Step::Key(k), Some(t), _) => t
                    .iter()
                    .find(|(key, _)| &**key.get_ref() == k)
                    .map(|(key, v)| (key.span(), v)),
                (Step::Index(i), _, Some(v)) => match v.get_ref() {
                    DeValue::Array(a) => a.get(i).map(|e| (e.span(), e)),
                    _ => None,
                },
                _ => None,
            };
            let Some((span, v)) = next else {
                break;
            };
            best = span;
            value = Some(v);
            table = match v.get_ref() {
                DeValue::Table(t) => Some(t),
                _ => None,
            };
        }
        best
    }

    /// An input error at the key named by `steps` (or its deepest existing
    /// parent).
    #[must_use]
    pub fn err(&self, steps: &[Step], message: String) -> SynthError {
        error_at(self.path, self.text, self.span(steps).start, message)
    }
}

/// A key path as `steps!["camera", "fx"]` or `steps!["markers", i, "id"]`.
macro_rules! steps {
    ($($s:expr),* $(,)?) => {
        &[$($crate::toml_input::Step::from($s)),*]
    };
}
pub(crate) use steps;
