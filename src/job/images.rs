//! Small helpers of the photo-side jobs (camera, env merge, env orient):
//! file names for reports, the image types of `lucent_calib` and ours, and
//! the warning about a board whose corner (0, 0) is ambiguous.

use crate::imageio;
use lucent_calib::scene::BoardSpec;
use lucent_calib::RgbBuffer;
use std::path::Path;

/// A path's file name (the whole path when it has none).
pub fn file_name(path: &Path) -> String {
    path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| path.display().to_string())
}

/// An image as the RGB buffer of `lucent_calib`.
pub fn to_buffer(img: imageio::RgbImage) -> RgbBuffer {
    RgbBuffer { width: img.width, height: img.height, data: img.data }
}

/// An RGB buffer of `lucent_calib` as an image.
pub fn to_image(buf: RgbBuffer) -> imageio::RgbImage {
    imageio::RgbImage { width: buf.width, height: buf.height, data: buf.data }
}

/// The warning of `pose` and `env orient` when corner (0, 0) cannot be
/// told from the opposite one (without its "warning: ").
pub fn ambiguous_board_warning(board: &BoardSpec, what: &str) -> String {
    format!(
        "corner (0, 0) of the {}x{} board cannot be told from the opposite corner (a board with two even \
         or two odd counts looks the same turned 180°, or its outer corner squares are not both visible): {what} \
         may be off by 180°; use a board with one odd and one even count, e.g. 9x6, seen whole",
        board.cols, board.rows
    )
}
