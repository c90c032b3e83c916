//! Print-ready SVG of tags and tag sheets.
