//! A borrowed 8-bit grey image: what the detector and the decoder read.
//!
//! Camera drivers hand out frames as a byte buffer with a row stride that
//! may be wider than the image (rows padded for alignment). A [`GrayView`]
//! describes such a buffer as it is, so a frame is detected without being
//! copied into an owned image first; an `&image::GrayImage` converts into
//! one for free.

use image::GrayImage;

use crate::{Error, Result};

/// A borrowed grey image: `height` rows of `width` bytes, row `y` starting
/// at byte `y * stride` of `data`.
#[derive(Debug, Clone, Copy)]
pub struct GrayView<'a> {
    data: &'a [u8],
    width: u32,
    height: u32,
    stride: usize,
}

impl<'a> GrayView<'a> {
    /// A view of `data` as `width` x `height` pixels with rows `stride`
    /// bytes apart. Fails when the stride is narrower than a row or `data`
    /// is too short for the last row (it may end right after it).
    pub fn new(data: &'a [u8], width: u32, height: u32, stride: usize) -> Result<Self> {
        let bad = |reason: String| Error::InvalidParameter {
            name: "image view",
            reason,
        };
        let w = width as usize;
        if stride < w {
            return Err(bad(format!("row stride {stride} is below the width {w}")));
        }
        let need = match height {
            0 => 0,
            h => (h as usize - 1)
                .checked_mul(stride)
                .and_then(|n| n.checked_add(w))
                .ok_or_else(|| bad("size overflows".into()))?,
        };
        if data.len() < need {
            return Err(bad(format!(
                "{width} x {height} pixels with stride {stride} need {need} bytes, got {}",
                data.len()
            )));
        }
        Ok(Self {
            data,
            width,
            height,
            stride,
        })
    }

    /// A packed buffer the crate made itself (`data.len() == w * h`): the
    /// tests' images, the upsampled small-tag regions.
    pub(crate) fn packed(data: &'a [u8], width: usize, height: usize) -> Self {
        debug_assert_eq!(data.len(), width * height);
        Self {
            data,
            width: width as u32,
            height: height as u32,
            stride: width,
        }
    }

    /// Width in pixels.
    #[inline]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    #[inline]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Bytes from one row's start to the next's.
    #[inline]
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// The underlying bytes (row `y` starts at `y * stride`).
    #[inline]
    pub fn data(&self) -> &'a [u8] {
        self.data
    }

    /// Row `y` (`width` bytes). Panics when `y >= height`.
    #[inline]
    pub fn row(&self, y: usize) -> &'a [u8] {
        let start = y * self.stride;
        &self.data[start..start + self.width as usize]
    }

    /// The `w` x `h` rectangle whose top-left pixel is `(x0, y0)`, clipped
    /// to the image: a view of the same bytes, no copy.
    pub(crate) fn crop(&self, x0: u32, y0: u32, w: u32, h: u32) -> GrayView<'a> {
        let x0 = x0.min(self.width);
        let y0 = y0.min(self.height);
        let w = w.min(self.width - x0);
        let h = h.min(self.height - y0);
        if w == 0 || h == 0 {
            return GrayView {
                data: &[],
                width: 0,
                height: 0,
                stride: 0,
            };
        }
        let start = y0 as usize * self.stride + x0 as usize;
        let end = start + (h as usize - 1) * self.stride + w as usize;
        GrayView {
            data: &self.data[start..end],
            width: w,
            height: h,
            stride: self.stride,
        }
    }

    /// The grey level at `(x, y)`, `None` outside the image.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Option<u8> {
        (x < self.width && y < self.height)
            .then(|| self.data[y as usize * self.stride + x as usize])
    }
}

impl<'a> From<&'a GrayImage> for GrayView<'a> {
    fn from(img: &'a GrayImage) -> Self {
        Self {
            data: img.as_raw(),
            width: img.width(),
            height: img.height(),
            stride: img.width() as usize,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_short_buffers_and_narrow_strides() {
        let data = [0u8; 10];
        assert!(GrayView::new(&data, 4, 2, 3).is_err());
        assert!(GrayView::new(&data, 4, 3, 4).is_err());
        // The last row may end at the buffer's end: 2 * 4 + 2 = 10.
        let v = GrayView::new(&data, 2, 3, 4).unwrap();
        assert_eq!(v.row(2).len(), 2);
        assert!(GrayView::new(&data, 0, 0, 0).is_ok());
    }

    #[test]
    fn reads_through_the_stride() {
        let data = [1u8, 2, 99, 3, 4, 99];
        let v = GrayView::new(&data, 2, 2, 3).unwrap();
        assert_eq!(v.get(1, 1), Some(4));
        assert_eq!(v.get(2, 0), None);
        assert_eq!(v.row(1), &[3, 4]);
    }

    #[test]
    fn crops_share_the_bytes_and_clip_to_the_image() {
        let data: Vec<u8> = (0..20).collect();
        let v = GrayView::new(&data, 4, 4, 5).unwrap();
        let c = v.crop(1, 2, 2, 2);
        assert_eq!((c.width(), c.height(), c.stride()), (2, 2, 5));
        assert_eq!(c.row(0), &[11, 12]);
        assert_eq!(c.row(1), &[16, 17]);
        let c = v.crop(3, 3, 10, 10);
        assert_eq!((c.width(), c.height()), (1, 1));
        assert_eq!(c.get(0, 0), Some(18));
        assert_eq!(v.crop(4, 0, 2, 2).width(), 0);
    }
}
