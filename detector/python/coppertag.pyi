"""CopperTag fiducial markers: detection, pose and generation.

``Detector(...).detect(grey_uint8_array)`` returns a list of ``Detection``;
``generate(family, id, px=...)`` returns the tag as a uint8 image;
``generate_svg(family, id, size_mm=...)`` returns SVG text. Pixel-centre
coordinates (the centre of the top-left pixel is (0, 0), x right, y down);
corners TL, BL, BR, TR of the white data square; metres and radians.
"""

from typing import Any, Iterable, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str
#: Every Detector setting (keyword) and its default.
DEFAULT_SETTINGS: dict[str, Any]
#: Smallest image side detect() accepts, in pixels.
MIN_IMAGE_SIDE: int
#: The built-in family names.
FAMILIES: list[str]

class PoseError(ValueError):
    """No pose fits the tag's corners (degenerate or inconsistent with a
    planar square seen by the camera)."""

class Pose:
    """One pose of a tag in the camera frame: X_cam = rotation @ X_tag + translation.

    Tag frame: origin at the data square's centre, x towards the tag's right
    side, y towards its bottom, z into the tag (a tag squarely facing the
    camera has the identity rotation). Camera frame: OpenCV's (x right, y
    down, z forward).
    """

    @property
    def rotation(self) -> npt.NDArray[np.float64]:
        """3 x 3 rotation matrix (tag frame to camera frame)."""
    @property
    def rotation_vector(self) -> npt.NDArray[np.float64]:
        """The rotation as axis times angle (radians), shape (3,), as cv2.Rodrigues gives it."""
    @property
    def translation(self) -> npt.NDArray[np.float64]:
        """Tag centre in the camera frame, shape (3,), in the unit of tag_size (metres)."""
    @property
    def reprojection_error(self) -> float:
        """RMS reprojection error of the four corners, pixels."""

class Detection:
    """One detected tag (read-only)."""

    @property
    def family(self) -> str:
        """Family name: "ct14" or "ct8"."""
    @property
    def id(self) -> int:
        """Decoded id."""
    @property
    def corners(self) -> npt.NDArray[np.float64]:
        """Corners TL, BL, BR, TR of the data square, a 4 x 2 array of (x, y) pixels."""
    @property
    def estimated(self) -> Tuple[bool, bool, bool, bool]:
        """Per corner (TL, BL, BR, TR): hidden and estimated rather than measured."""
    @property
    def corner_sigma(self) -> Optional[Tuple[float, float, float, float]]:
        """Per corner (TL, BL, BR, TR): one-sigma uncertainty in pixels from the fit
        of the tag's own model to its visible edges; None when the tag was too small
        or too hidden for that fit."""
    @property
    def corrected(self) -> int:
        """Reed-Solomon symbols corrected while decoding (0: a clean read); for a
        tag read by likelihood, the symbols a cell-by-cell reading got wrong."""
    @property
    def likelihood(self) -> bool:
        """True for a blurred tag read by matching its cells against every
        codeword (the code could not read it); its geometry was confirmed by
        the model fit."""
    @property
    def center(self) -> Tuple[float, float]:
        """Image point (x, y) of the tag centre (where the diagonals cross)."""
    @property
    def contrast(self) -> float:
        """Measured contrast between the tag's white and black, grey levels."""
    @property
    def homography(self) -> npt.NDArray[np.float64]:
        """3 x 3 homography from tag units (data square of side 1, centre 0, y down) to pixels."""
    def pose(self, fx: float, fy: float, cx: float, cy: float, tag_size: float) -> Tuple[Pose, Pose]:
        """The tag's two poses (IPPE), the better (smaller reprojection error) first.

        fx, fy, cx, cy: pinhole intrinsics in pixels of an undistorted image;
        tag_size: side of the white data square (half the printed tag), metres.
        Raises ValueError for bad input, PoseError when no pose fits.
        """

FamilyArg = Union[str, Tuple[str, int]]

class Detector:
    """Finds and decodes CopperTags in grey images.

    families: names ("ct14", "ct8") or (name, max_corrected) pairs, tried in
    order. Every other keyword is a setting of the Rust DetectorConfig with
    the same default (DEFAULT_SETTINGS); a bad value raises ValueError naming
    the setting, an unknown keyword TypeError. Reuse one detector per thread:
    detect() releases the GIL, so detectors in several threads run in parallel.
    """

    def __init__(
        self,
        families: Optional[Iterable[FamilyArg]] = ("ct14", "ct8"),
        *,
        downsample: int = 2,
        threshold_radius: int = 10,
        threshold_offset: int = 6,
        min_contour_points: int = 12,
        dp_epsilon: float = 1.5,
        min_line_length: float = 8.0,
        corner_min_angle_deg: float = 22.5,
        corner_max_gap: float = 7.0,
        ellipse_min_minor: float = 4.0,
        ellipse_max_rms: float = 1.0,
        quad_min_side: float = 4.0,
        edge_max_angle_deg: float = 20.0,
        recover_occluded: bool = True,
        refine_corners: bool = True,
        small_tags: bool = True,
        max_candidates: int = 400,
        threads: int = 1,
        pin_threads: bool = True,
    ) -> None: ...
    def detect(self, image: npt.NDArray[np.uint8]) -> list[Detection]:
        """Every tag in a 2-D uint8 grey image, sorted by family and id.

        Any strides: rows of adjacent pixels (C order, ROI slices) are read in
        place, other layouts copied once. Colour images are not converted (use
        cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)). TypeError for a non-array or
        another dtype, ValueError for another shape or an image smaller than
        MIN_IMAGE_SIDE. Releases the GIL while it runs.
        """
    @property
    def stats(self) -> dict[str, float]:
        """Per-stage times of the last detect() call, in seconds, then "total"."""
    @property
    def settings(self) -> dict[str, Any]:
        """The settings in force (every keyword but families)."""
    @property
    def families(self) -> list[Tuple[str, int]]:
        """The families decoded, in order, as (name, correction limit) pairs."""

def reads_in_place(image: npt.NDArray[np.uint8]) -> bool:
    """Whether detect() reads `image` in place (True) or copies it first (False)."""

def generate(family: str, id: int, px: int = 1024) -> npt.NDArray[np.uint8]:
    """Tag `id` of `family` as a px x px uint8 image (white background; the data
    square is the middle half). ValueError for a bad family, id or px (16..=16384)."""

def generate_svg(family: str, id: int, size_mm: float = 100.0) -> str:
    """Tag `id` of `family` as SVG text, size_mm millimetres on a side (the whole tag)."""
