//! The chessboard of a calibration: inner corners along a row and a column,
//! the square size in metres, and corner positions in the board frame
//! (origin at inner corner (0, 0), x along the corner index i, y along j,
//! z = 0 on the board). A leaf module.
//!
//! ```
//! use lucent_calib::board::BoardSpec;
//! // A board of 10 × 7 squares of 25 mm has 9 × 6 inner corners.
//! let b = BoardSpec::parse("9x6", 25.0).unwrap();
//! assert_eq!(b.corners().len(), 54);
//! assert_eq!(b.corner(2, 1), [0.05, 0.025, 0.0]);
//! ```

use serde::{Deserialize, Serialize};

/// A chessboard: inner corners and square size.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoardSpec {
    /// Inner corners along a row (index i).
    pub cols: usize,
    /// Inner corners along a column (index j).
    pub rows: usize,
    pub square_m: f64,
}

/// What is wrong with a board given as text ([`BoardSpec::parse`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BoardError {
    #[error("board {text:?}: expected COLSxROWS inner corners, e.g. 9x6 (a board of 10 × 7 squares)")]
    Syntax { text: String },
    #[error("board {text:?}: needs at least 3 × 3 inner corners (OpenCV's detectors)")]
    TooSmall { text: String },
    #[error("board {text:?}: at most {MAX_CORNERS} inner corners per side")]
    TooLarge { text: String },
    #[error("square size {square_mm} mm: must lie in 0.001 … 10000 mm")]
    Square { square_mm: f64 },
}

/// The most inner corners along a side of a board.
pub const MAX_CORNERS: usize = 200;

/// The inner corners of a chessboard, 3 … [`MAX_CORNERS`] along each side.
///
/// As text (its `FromStr`, `Display` and serde form) "COLSxROWS", e.g.
/// "9x6" for a board of 10 × 7 squares ("9X6" and "9×6" are read too, and
/// written "9x6").
///
/// ```
/// use lucent_calib::board::BoardSize;
/// let b: BoardSize = "9 × 6".parse().unwrap();
/// assert_eq!((b.cols, b.rows), (9, 6));
/// assert_eq!(b.to_string(), "9x6");
/// assert!("9".parse::<BoardSize>().unwrap_err().to_string().contains("\"9\""));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardSize {
    /// Inner corners along a row (index i).
    pub cols: usize,
    /// Inner corners along a column (index j).
    pub rows: usize,
}

impl std::str::FromStr for BoardSize {
    type Err = BoardError;

    fn from_str(text: &str) -> Result<Self, BoardError> {
        let bad = || BoardError::Syntax { text: text.to_string() };
        let (a, b) = text.trim().split_once(['x', 'X', '×']).ok_or_else(bad)?;
        let cols: usize = a.trim().parse().map_err(|_| bad())?;
        let rows: usize = b.trim().parse().map_err(|_| bad())?;
        if cols < 3 || rows < 3 {
            return Err(BoardError::TooSmall { text: text.to_string() });
        }
        if cols > MAX_CORNERS || rows > MAX_CORNERS {
            return Err(BoardError::TooLarge { text: text.to_string() });
        }
        Ok(Self { cols, rows })
    }
}

impl std::fmt::Display for BoardSize {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}x{}", self.cols, self.rows)
    }
}

impl Serialize for BoardSize {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for BoardSize {
    /// "COLSxROWS", refused with the text and the reason.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        String::deserialize(d)?.parse().map_err(serde::de::Error::custom)
    }
}

impl BoardSpec {
    /// From "COLSxROWS" (inner corners, e.g. "9x6") and the square size in mm.
    pub fn parse(text: &str, square_mm: f64) -> Result<Self, BoardError> {
        Self::new(text.parse()?, square_mm)
    }

    /// From its inner corners and the square size in mm.
    pub fn new(size: BoardSize, square_mm: f64) -> Result<Self, BoardError> {
        Self::check_square_mm(square_mm)?;
        Ok(Self { cols: size.cols, rows: size.rows, square_m: square_mm / 1000.0 })
    }

    /// A square size every reader of one accepts: 0.001 … 10000 mm.
    pub fn check_square_mm(square_mm: f64) -> Result<(), BoardError> {
        if (1e-3..=1e4).contains(&square_mm) {
            Ok(())
        } else {
            Err(BoardError::Square { square_mm })
        }
    }

    /// Corner (i, j) in board coordinates (metres, z = 0).
    pub fn corner(&self, i: usize, j: usize) -> [f64; 3] {
        [i as f64 * self.square_m, j as f64 * self.square_m, 0.0]
    }

    /// All inner corners, i fastest (OpenCV's order).
    pub fn corners(&self) -> Vec<[f64; 3]> {
        (0..self.rows).flat_map(|j| (0..self.cols).map(move |i| (i, j))).map(|(i, j)| self.corner(i, j)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn board_parsing() {
        let b = BoardSpec::parse("9x6", 25.0).unwrap();
        assert_eq!((b.cols, b.rows), (9, 6));
        assert!((b.square_m - 0.025).abs() < 1e-15);
        assert_eq!(b.corners()[1], [0.025, 0.0, 0.0]);
        assert_eq!(b.corners()[9], [0.0, 0.025, 0.0]);
        assert!(BoardSpec::parse("9", 25.0).unwrap_err().to_string().contains("COLSxROWS"));
        assert!(BoardSpec::parse("2x6", 25.0).is_err());
        assert!(BoardSpec::parse("9x6", 0.0).is_err());
        assert!(BoardSpec::parse("9x6", f64::NAN).is_err());
    }
}
