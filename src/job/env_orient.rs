//! The env-orient job: [`EnvOrientJob::run`] turns an equirectangular map
//! as the 360° camera made it into the board's world (`lucent env orient`;
//! views, detection geometry and the turn are [`lucent_calib::env`],
//! docs/guide.md#environments).
//!
//! The turn is a yaw about the zenith, world = R_z(yaw) · map (the
//! renderer's `[environment] yaw_deg`), either given or found from the
//! board: a perspective view of the map ([`env::perspective_view`]) is cut
//! where the board is, its inner corners found and numbered as `lucent
//! pose` numbers them, the board's pose in the view solved (PnP) and
//! carried into the map's frame ([`env::board_in_map`]); the yaw puts the
//! board's i axis along world +x. A board whose normal is further than
//! `max_tilt_deg` from the zenith is refused (a yaw cannot level a map).
//!
//! It writes, named after the job's `out` ([`EnvOrientFiles`]), all or none:
//! * `NAME.exr` — the map turned by the yaw, 32-bit float RGB (render it
//!   with yaw 0);
//! * `NAME.json` — the [`Orientation`]: the source's and output's names,
//!   the yaw of each, how it was found and, from a board, the view, the
//!   detector, the corner order, the PnP RMS in view pixels and the board's
//!   axes and tilt in the map;
//! * `NAME_board.png` (from a board) — the view with the detected and
//!   reprojected corners.

use super::context::Context;
use super::fields::{bad, board, s, JobError, Line};
use super::images::{ambiguous_board_warning, file_name, to_buffer, to_image};
use super::values::ImageSize;
use crate::imageio::{self, extension, ImageIoError};
use crate::io::{json_bytes, WriteError};
use crate::text::serde_as_text;
use lucent_calib::board::{BoardError, BoardSize};
use lucent_calib::camera::{CameraModel, Distortion, DistortionModel};
use lucent_calib::env::{self, BoardFound, EnvError, Orientation, ViewSpec};
use lucent_calib::error::CalibError;
use lucent_calib::scene::sibling;
use lucent_calib::{cv, GrayImage, RgbBuffer};
use lucent_render::env::MAX_YAW_DEG;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// `lucent env orient`: a map turned to the board's world, by a given yaw
/// or from the board found in a view of it ([`EnvOrientJob::run`]). The
/// keys unset or at their defaults may be left out of a job file and are
/// not written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvOrientJob {
    /// The equirectangular map (.exr or .hdr, 2:1).
    pub input: PathBuf,
    /// `--yaw`: the turn in degrees, if known (else `board_view`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub yaw: Option<f64>,
    /// `--board-view`: the view that shows the board ("YAW,PITCH,FOV" in degrees as text).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub board_view: Option<ViewAngles>,
    /// `--board`: inner corners of the board ("COLSxROWS" as text), with `board_view`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub board: Option<BoardSize>,
    /// `--square-mm`: side of one square, with `board_view`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub square_mm: Option<f64>,
    /// `--view-size`: the board view's size ("WIDTHxHEIGHT" as text).
    #[serde(default = "default_view_size", skip_serializing_if = "is_default_view_size")]
    pub view_size: ImageSize,
    /// `--max-tilt-deg`: the largest angle between the board's normal and the map's zenith.
    #[serde(default = "default_max_tilt_deg", skip_serializing_if = "is_default_max_tilt_deg")]
    pub max_tilt_deg: f64,
    /// The turned map (.exr); its orientation and board view go beside it.
    pub out: PathBuf,
}

/// The defaults of `lucent env orient --view-size` and `--max-tilt-deg`.
pub const DEFAULT_VIEW_SIZE: ImageSize = ImageSize { width: 1600, height: 1200 };
pub const DEFAULT_MAX_TILT_DEG: f64 = 10.0;

fn default_view_size() -> ImageSize {
    DEFAULT_VIEW_SIZE
}
fn is_default_view_size(s: &ImageSize) -> bool {
    *s == DEFAULT_VIEW_SIZE
}
fn default_max_tilt_deg() -> f64 {
    DEFAULT_MAX_TILT_DEG
}
fn is_default_max_tilt_deg(v: &f64) -> bool {
    *v == DEFAULT_MAX_TILT_DEG
}

impl EnvOrientJob {
    /// `input` turned by `yaw` degrees into `out`.
    pub fn given_yaw(input: PathBuf, yaw: f64, out: PathBuf) -> Self {
        EnvOrientJob {
            input,
            yaw: Some(yaw),
            board_view: None,
            board: None,
            square_mm: None,
            view_size: DEFAULT_VIEW_SIZE,
            max_tilt_deg: DEFAULT_MAX_TILT_DEG,
            out,
        }
    }

    /// The view of the board, of `view_size`.
    fn view_spec(&self, v: &ViewAngles) -> ViewSpec {
        ViewSpec {
            yaw_deg: v.yaw_deg,
            pitch_deg: v.pitch_deg,
            fov_deg: v.fov_deg,
            width: self.view_size.width,
            height: self.view_size.height,
        }
    }

    /// The yaw or the board's view (one of them), each within its range;
    /// a view needs its board.
    pub fn validate(&self) -> Result<(), JobError> {
        match (self.yaw, &self.board_view) {
            (Some(_), Some(v)) => return Err(bad("board_view", v, "give --yaw or --board-view, not both")),
            (None, None) => {
                return Err(bad("yaw", "", "give the turn (--yaw) or the view that shows the board (--board-view)"));
            }
            _ => {}
        }
        if let Some(y) = self.yaw
            && !(y.is_finite() && y.abs() <= MAX_YAW_DEG)
        {
            return Err(bad("yaw", y, format!("must be a finite number of degrees within ±{MAX_YAW_DEG}°")));
        }
        if !(self.max_tilt_deg.is_finite() && self.max_tilt_deg > 0.0) {
            return Err(bad("max_tilt_deg", self.max_tilt_deg, "must be a positive number of degrees"));
        }
        if let Some(v) = &self.board_view {
            self.view_spec(v).camera().map_err(|e| bad("board_view", v, e.to_string()))?;
            let (Some(b), Some(square_mm)) = (self.board, self.square_mm) else {
                return Err(bad("board_view", v, "needs --board and --square-mm (the board to find)"));
            };
            board(b, square_mm)?;
        }
        Ok(())
    }

    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["env", "orient"]);
        l.word(s(&self.input));
        if let Some(y) = self.yaw {
            l.word(format!("--yaw={y}"));
        }
        if let Some(v) = &self.board_view {
            l.word(format!("--board-view={v}"));
        }
        l.opt("--board", &self.board);
        if let Some(sq) = self.square_mm {
            l.word(format!("--square-mm={sq}"));
        }
        if !is_default_view_size(&self.view_size) {
            l.flag("--view-size", self.view_size);
        }
        if !is_default_max_tilt_deg(&self.max_tilt_deg) {
            l.word(format!("--max-tilt-deg={}", self.max_tilt_deg));
        }
        l.flag("--out", s(&self.out));
        l.0
    }
}

/// The direction and width of a view cut from a map, in degrees: the view
/// axis's azimuth (counter-clockwise from the map's +x seen from above) and
/// elevation, and the horizontal field of view (as `lucent env view`'s
/// `--yaw`, `--pitch`, `--fov`).
///
/// As text "YAW,PITCH,FOV", e.g. "0,-90,100" (straight down, 100° wide;
/// written back in the numbers' shortest form). The ranges are the view's
/// ([`ViewSpec::camera`]).
///
/// ```
/// use lucent::job::ViewAngles;
/// let v: ViewAngles = "0, -90, 100.0".parse().unwrap();
/// assert_eq!((v.yaw_deg, v.pitch_deg, v.fov_deg), (0.0, -90.0, 100.0));
/// assert_eq!(v.to_string(), "0,-90,100");
/// assert!("0,-90".parse::<ViewAngles>().unwrap_err().to_string().contains("\"0,-90\""));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewAngles {
    pub yaw_deg: f64,
    pub pitch_deg: f64,
    pub fov_deg: f64,
}

/// View angles written as text that are not ([`ViewAngles`]).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{text:?}: expected YAW,PITCH,FOV in degrees, e.g. 0,-90,100")]
pub struct ViewAnglesError {
    pub text: String,
}

impl std::str::FromStr for ViewAngles {
    type Err = ViewAnglesError;

    fn from_str(text: &str) -> Result<Self, ViewAnglesError> {
        let bad = || ViewAnglesError { text: text.into() };
        let v: Vec<f64> =
            text.split(',').map(|s| s.trim().parse::<f64>()).collect::<Result<_, _>>().map_err(|_| bad())?;
        let [yaw_deg, pitch_deg, fov_deg] = <[f64; 3]>::try_from(v).map_err(|_| bad())?;
        Ok(ViewAngles { yaw_deg, pitch_deg, fov_deg })
    }
}

impl std::fmt::Display for ViewAngles {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{},{}", self.yaw_deg, self.pitch_deg, self.fov_deg)
    }
}

serde_as_text!(ViewAngles);

/// The files of an orientation, each name spelled here once: the turned
/// map (`exr`, the job's `out`), beside it the [`Orientation`] (`json`,
/// `NAME.json`) and, from a board, the view with its corners (`board_png`,
/// `NAME_board.png`).
///
/// ```
/// use lucent::job::EnvOrientFiles;
/// let f = EnvOrientFiles::of(std::path::Path::new("env/pano_oriented.exr"));
/// assert_eq!(f.json, std::path::Path::new("env/pano_oriented.json"));
/// assert_eq!(f.board_png, std::path::Path::new("env/pano_oriented_board.png"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EnvOrientFiles {
    pub exr: PathBuf,
    pub json: PathBuf,
    pub board_png: PathBuf,
}

impl EnvOrientFiles {
    /// The files of the orientation whose turned map is `exr`.
    pub fn of(exr: &Path) -> Self {
        Self { exr: exr.to_path_buf(), json: sibling(exr, ".json"), board_png: sibling(exr, "_board.png") }
    }
}

/// An equirectangular map that cannot be read ([`read_env_map`]).
#[derive(Debug, Error)]
pub enum EnvMapError {
    #[error("{}: an HDR environment must be .exr or .hdr", .0.display())]
    NotHdr(PathBuf),
    #[error(transparent)]
    Image(#[from] ImageIoError),
    /// Not 2:1, or a value that is not finite (the message names the file).
    #[error("{}", path.display())]
    Map { path: PathBuf, source: EnvError },
}

/// An equirectangular HDR map (.exr or .hdr), checked: 2:1 and finite.
pub fn read_env_map(path: &Path) -> Result<RgbBuffer, EnvMapError> {
    let e = extension(path);
    if e != "exr" && e != "hdr" {
        return Err(EnvMapError::NotHdr(path.to_path_buf()));
    }
    let img = to_buffer(imageio::read_rgb(path)?);
    let named = |source| EnvMapError::Map { path: path.to_path_buf(), source };
    env::check_equirectangular(img.width, img.height).map_err(named)?;
    env::check_finite(&img).map_err(named)?;
    Ok(img)
}

/// Why an orientation failed; every variant names the file or flag.
#[derive(Debug, Error)]
pub enum EnvOrientError {
    #[error(transparent)]
    Invalid(#[from] JobError),
    #[error(transparent)]
    Map(#[from] EnvMapError),
    #[error(transparent)]
    Board(#[from] BoardError),
    #[error(transparent)]
    View(#[from] EnvError),
    /// Corner detection, PnP or drawing the board view.
    #[error(transparent)]
    Detect(#[from] CalibError),
    #[error(
        "{}: no chessboard of {cols}x{rows} inner corners in the view --board-view {view} (yaw {}°, pitch {}°, fov \
         {}°); cut it with `lucent env view` to look, and aim the view at the board",
        input.display(),
        view.yaw_deg,
        view.pitch_deg,
        view.fov_deg
    )]
    NoBoard { input: PathBuf, cols: usize, rows: usize, view: ViewAngles },
    #[error(
        "{}: the board's normal is {tilt_deg:.1}° from the map's zenith (more than --max-tilt-deg {max_tilt_deg}): \
         either the board is not the level one the scene stands on or the 360° camera was not level; a yaw cannot \
         align them",
        input.display()
    )]
    Tilted { input: PathBuf, tilt_deg: f64, max_tilt_deg: f64 },
    #[error(transparent)]
    Image(#[from] ImageIoError),
    #[error(transparent)]
    Write(#[from] WriteError),
}

/// What an orientation found and wrote.
pub struct EnvOrientRun {
    /// The map as the camera made it.
    pub input: PathBuf,
    /// The files written (`board_png` only when the board was found).
    pub files: EnvOrientFiles,
    /// `NAME.json`.
    pub orientation: Orientation,
}

impl EnvOrientRun {
    /// What `lucent env orient` prints on its standard output.
    pub fn summary(&self) -> Vec<String> {
        let yaw = self.orientation.source_yaw_deg;
        let first = match &self.orientation.board {
            Some(b) => format!(
                "board {} found in the view (yaw {}°, pitch {}°, fov {}°; {} detector, PnP RMS {:.3} px, corner order \
                 {:?}): its i axis points {:.2}° from the map's +x, tilt {:.2}° from level, corner (0, 0) {:.3} m \
                 away; yaw {:.3}°",
                b.board,
                b.view.yaw_deg,
                b.view.pitch_deg,
                b.view.fov_deg,
                b.detector,
                b.pnp_rms_px,
                b.corner_order,
                -yaw,
                b.in_map.tilt_deg,
                b.in_map.corner00_distance_m,
                yaw
            ),
            None => format!("given yaw {yaw}°"),
        };
        let board_png = self.orientation.board.is_some();
        vec![
            first,
            format!(
                "{} turned by {yaw:.3}° → {} (render with yaw 0; or render {} with yaw_deg = {yaw:.3}); orientation {}{}",
                self.input.display(),
                self.files.exr.display(),
                file_name(&self.input),
                self.files.json.display(),
                if board_png { format!(", board view {}", self.files.board_png.display()) } else { String::new() }
            ),
        ]
    }
}

type E = EnvOrientError;

impl EnvOrientJob {
    /// Reads the map, finds the yaw (given, or from the board in the
    /// view), turns the map and writes it with its orientation (and the
    /// board view) ([`EnvOrientFiles`]). A board whose corner (0, 0) cannot
    /// be told from the opposite one is warned of.
    pub fn run(&self, ctx: &Context) -> Result<EnvOrientRun, E> {
        // Parameters are checked before the map is read.
        self.validate()?;
        let setup = match (&self.board_view, self.board, self.square_mm) {
            (Some(v), Some(b), Some(square_mm)) => {
                Some((*v, self.view_spec(v), lucent_calib::board::BoardSpec::new(b, square_mm)?, square_mm))
            }
            _ => None,
        };
        let map = read_env_map(&self.input)?;
        let (yaw, found, png) = match setup {
            None => (self.yaw.unwrap_or(0.0), None, None),
            Some((angles, spec, board, square_mm)) => {
                let (view, cam) = env::perspective_view(&map, &spec)?;
                let gray = GrayImage::from_linear_rgb(&view);
                let (corners, order) = lucent_calib::scene::find_board_corners(&gray, &board)?.ok_or_else(|| {
                    E::NoBoard { input: self.input.clone(), cols: board.cols, rows: board.rows, view: angles }
                })?;
                let points = corners.points.clone();
                let pinhole = CameraModel {
                    model: DistortionModel::PinholeK3,
                    image_width: spec.width,
                    image_height: spec.height,
                    intrinsics: env::view_intrinsics(&cam),
                    distortion: Distortion::default(),
                };
                let pose = cv::solve_pnp(&points, &board, &pinhole)?;
                let reprojected: Vec<[f64; 2]> = board
                    .corners()
                    .iter()
                    .map(|p| pinhole.project(pose.to_camera(*p)).unwrap_or([f64::NAN; 2]))
                    .collect();
                let ss: f64 =
                    points.iter().zip(&reprojected).map(|(d, r)| (d[0] - r[0]).powi(2) + (d[1] - r[1]).powi(2)).sum();
                let rms = (ss / points.len() as f64).sqrt();
                let in_map = env::board_in_map(&cam, &pose.rotation, pose.translation_m);
                if in_map.tilt_deg.is_nan() || in_map.tilt_deg > self.max_tilt_deg {
                    return Err(E::Tilted {
                        input: self.input.clone(),
                        tilt_deg: in_map.tilt_deg,
                        max_tilt_deg: self.max_tilt_deg,
                    });
                }
                if order == env::CornerOrder::Ambiguous {
                    ctx.warn(&ambiguous_board_warning(&board, "the yaw"));
                }
                let label = format!("board in view: PnP RMS {rms:.3} px, yaw {:.2} deg", in_map.yaw_deg);
                let png = cv::draw_view_png(&gray, &board, &points, &reprojected, &[], &label)?;
                let yaw = in_map.yaw_deg;
                let found = BoardFound {
                    view: spec,
                    board: format!("{}x{}", board.cols, board.rows),
                    square_mm,
                    detector: corners.detector.to_string(),
                    corner_order: order,
                    pnp_rms_px: rms,
                    in_map,
                };
                (yaw, Some(found), Some(png))
            }
        };
        let turned = env::rotate_yaw(&map, yaw)?;
        let files = EnvOrientFiles::of(&self.out);
        let orientation = Orientation {
            convention: env::ORIENTATION_CONVENTION.into(),
            source: file_name(&self.input),
            source_yaw_deg: yaw,
            output: file_name(&files.exr),
            output_yaw_deg: 0.0,
            method: if found.is_some() { "board" } else { "given" }.into(),
            board: found,
        };
        let json = json_bytes(&files.json, &orientation)?;
        let exr = imageio::encode_exr(&files.exr, &to_image(turned))?;
        let mut written: Vec<(&Path, &[u8])> = vec![(&files.json, &json), (&files.exr, &exr)];
        if let Some(png) = &png {
            written.insert(0, (&files.board_png, png));
        }
        crate::io::write_files_atomic(&written)?;
        Ok(EnvOrientRun { input: self.input.clone(), files, orientation })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn view_angles_read_three_numbers_and_name_a_bad_text() {
        let v: ViewAngles = " 20, -90 ,100.5".parse().unwrap();
        assert_eq!(v, ViewAngles { yaw_deg: 20.0, pitch_deg: -90.0, fov_deg: 100.5 });
        assert_eq!(v.to_string().parse::<ViewAngles>().unwrap(), v);
        for text in ["0,-90", "0,-90,100,1", "a,b,c", ""] {
            assert_eq!(text.parse::<ViewAngles>().unwrap_err(), ViewAnglesError { text: text.into() });
        }
    }

    #[test]
    fn an_orient_job_needs_a_yaw_or_a_board_view_within_range() {
        let job = EnvOrientJob::given_yaw("pano.exr".into(), -117.0, "o.exr".into());
        assert!(job.validate().is_ok());
        let e = EnvOrientJob { yaw: Some(f64::NAN), ..job.clone() }.validate().unwrap_err();
        assert_eq!(e.to_string(), "--yaw NaN: must be a finite number of degrees within ±3600°");
        let e = EnvOrientJob { max_tilt_deg: 0.0, ..job.clone() }.validate().unwrap_err();
        assert_eq!(e.to_string(), "--max-tilt-deg 0: must be a positive number of degrees");
        assert_eq!(EnvOrientJob { yaw: None, ..job.clone() }.validate().unwrap_err().field, "yaw");
        let view = Some("0,-90,100".parse().unwrap());
        let by_board = EnvOrientJob {
            yaw: None,
            board_view: view,
            board: Some("9x6".parse().unwrap()),
            square_mm: Some(30.0),
            ..job.clone()
        };
        assert!(by_board.validate().is_ok());
        assert_eq!(EnvOrientJob { yaw: Some(1.0), ..by_board.clone() }.validate().unwrap_err().field, "board_view");
        assert_eq!(EnvOrientJob { board: None, ..by_board.clone() }.validate().unwrap_err().field, "board_view");
        assert_eq!(
            EnvOrientJob { square_mm: Some(0.0), ..by_board.clone() }.validate().unwrap_err().field,
            "square_mm"
        );
        let e = EnvOrientJob { board_view: Some("0,-95,90".parse().unwrap()), ..by_board }.validate().unwrap_err();
        assert!(e.to_string().starts_with("--board-view 0,-95,90: view: pitch -95°"), "{e}");
    }
}
