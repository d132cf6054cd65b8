//! Typed command-line values shared by the commands that draw an image: `--size WIDTHxHEIGHT`,
//! `--camera YAW,PITCH,DISTANCE`, `--quality KEY=VALUE` and `tradeoff --knob NAME=V1,V2,...`,
//! each parsed (and, for quality knobs, checked against [`KNOB_SPECS`](thicket_core::quality::KNOB_SPECS)) by clap when the
//! command line is read, and
//! [`ViewArgs`], the options `render` and `bench` share through `#[command(flatten)]`.
//!
//! A parser's error is the part after clap's `invalid value '…' for '--flag <NAME>':`, so it
//! does not repeat the flag or the value.

use std::fmt;

use clap::Args;
use thicket_core::measure::KnobValues;
use thicket_core::quality::{KnobSpec, Quality};
use thicket_core::scene::{Document, OrbitCamera};

/// An image size, `--size WIDTHxHEIGHT` (`x` or `X`, spaces around the numbers allowed).
///
/// Any two whole numbers parse; the renderers refuse an empty or oversized image
/// (`1..=MAX_IMAGE_SIZE` per edge) with the project named, as before these were typed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageSize {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl ImageSize {
    /// Parses `WIDTHxHEIGHT` (clap's `value_parser` for `--size`).
    ///
    /// # Errors
    /// No `x` between the numbers, or a side that is not a whole number (negative, fractional,
    /// over `u32::MAX`).
    pub fn parse(text: &str) -> Result<Self, String> {
        let (w, h) = text
            .split_once(['x', 'X'])
            .ok_or_else(|| "expected WIDTHxHEIGHT, e.g. 800x600".to_owned())?;
        let side = |v: &str| {
            v.trim()
                .parse::<u32>()
                .map_err(|_| format!("{v:?} is not a whole number"))
        };
        Ok(Self {
            width: side(w)?,
            height: side(h)?,
        })
    }
}

impl fmt::Display for CameraArg {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // As typed: 1e38, not 39 digits.
        let short = |v: f32| {
            if v != 0.0 && !(1e-4..1e9).contains(&v.abs()) {
                format!("{v:e}")
            } else {
                v.to_string()
            }
        };
        write!(
            f,
            "{},{},{}",
            short(self.yaw_deg),
            short(self.pitch_deg),
            short(self.distance)
        )
    }
}

impl fmt::Display for ImageSize {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}x{}", self.width, self.height)
    }
}

/// An orbit camera override, `--camera YAW,PITCH,DISTANCE` in degrees and scene units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraArg {
    /// Rotation about +Y in degrees.
    pub yaw_deg: f32,
    /// Elevation in degrees.
    pub pitch_deg: f32,
    /// Eye distance from the target, in scene units.
    pub distance: f32,
}

impl CameraArg {
    /// Parses `YAW,PITCH,DISTANCE` (clap's `value_parser` for `--camera`).
    ///
    /// # Errors
    /// Not three numbers, a number that is not finite, or a distance that is not above 0
    /// (the renderers refuse such a camera; here it is said before the project is loaded).
    pub fn parse(text: &str) -> Result<Self, String> {
        let parts: Vec<f32> = text
            .split(',')
            .map(|p| p.trim().parse::<f32>())
            .collect::<Result<_, _>>()
            .map_err(|_| "expected YAW,PITCH,DISTANCE numbers".to_owned())?;
        let [yaw_deg, pitch_deg, distance] = parts[..] else {
            return Err("expected three numbers YAW,PITCH,DISTANCE".to_owned());
        };
        if !(yaw_deg.is_finite() && pitch_deg.is_finite() && distance.is_finite()) {
            return Err("YAW, PITCH and DISTANCE must be finite numbers".to_owned());
        }
        if distance <= 0.0 {
            return Err(format!("DISTANCE {distance} must be above 0"));
        }
        Ok(Self {
            yaw_deg,
            pitch_deg,
            distance,
        })
    }
}

/// One quality knob override, `--quality KEY=VALUE`, whose name is a [`KNOB_SPECS`](thicket_core::quality::KNOB_SPECS) row and
/// whose value that knob accepts (parses, in range).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct QualityArg {
    /// The knob's name, from [`KNOB_SPECS`](thicket_core::quality::KNOB_SPECS).
    pub name: &'static str,
    /// The value as given (trimmed), applied with [`Quality::set`].
    pub value: String,
}

impl QualityArg {
    /// Parses `KEY=VALUE` (clap's `value_parser` for `--quality`).
    ///
    /// # Errors
    /// No `=`, a name not in [`KNOB_SPECS`](thicket_core::quality::KNOB_SPECS) (the message lists the known ones), or a value
    /// the knob does not accept (the message says its range).
    pub fn parse(text: &str) -> Result<Self, String> {
        let (key, value) = text
            .split_once('=')
            .ok_or_else(|| "expected KEY=VALUE".to_owned())?;
        let key = key.trim();
        // Each knob is checked against its own range only, so setting it on the defaults
        // accepts exactly what setting it on any valid quality does.
        Quality::default()
            .set(key, value)
            .map_err(|e| e.to_string())?;
        // `set` refused every name without a row, so the row is there; its `'static` name is
        // what the argument keeps.
        let name = KnobSpec::named(key).map_or("", |k| k.name);
        Ok(Self {
            name,
            value: value.trim().to_owned(),
        })
    }
}

/// Parses `thicket tradeoff --knob NAME=V1,V2,...` (clap's `value_parser`): every value
/// is checked against the knob's [`KNOB_SPECS`](thicket_core::quality::KNOB_SPECS) row, as [`KnobValues::parse`] does.
///
/// # Errors
/// Malformed text, an unknown knob (the message lists the known ones) or a value the knob
/// does not accept.
pub fn parse_knob_values(text: &str) -> Result<KnobValues, String> {
    KnobValues::parse(text).map_err(|e| e.to_string())
}

/// The view options `render` and `bench` share: image size, camera and quality overrides.
#[derive(Debug, Clone, Args)]
pub struct ViewArgs {
    /// Image size as WIDTHxHEIGHT.
    #[arg(long, default_value = "800x800", value_parser = ImageSize::parse)]
    pub size: ImageSize,
    /// Orbit camera as YAW,PITCH,DISTANCE in degrees and scene units (default: the project's).
    #[arg(long, value_parser = CameraArg::parse)]
    pub camera: Option<CameraArg>,
    /// Quality knob as KEY=VALUE (repeatable), e.g. lod_pixel_threshold=2.
    #[arg(long = "quality", value_name = "KEY=VALUE", value_parser = QualityArg::parse)]
    pub quality: Vec<QualityArg>,
}

impl ViewArgs {
    /// The document's quality and camera with these overrides; see [`view_from`].
    ///
    /// # Errors
    /// A quality override the document's other knobs refuse (none do today: each knob is
    /// checked on its own).
    pub fn apply(&self, doc: &Document) -> anyhow::Result<(Quality, OrbitCamera)> {
        view_from(doc, &self.quality, self.camera)
    }
}

/// The document's quality with `quality` overrides applied in order, and its camera with a
/// `camera` override (whose near and far planes then enclose the scene).
///
/// # Errors
/// A quality value [`Quality::set`] refuses, or a `camera` override that leaves the camera
/// unusable (a distance so large its far plane is not finite): the option is named with the
/// field it breaks, not the project.
pub fn view_from(
    doc: &Document,
    quality: &[QualityArg],
    camera: Option<CameraArg>,
) -> anyhow::Result<(Quality, OrbitCamera)> {
    use anyhow::Context as _;
    let mut q = doc.quality.clone();
    for kv in quality {
        q.set(kv.name, &kv.value)
            .with_context(|| format!("--quality {}={}", kv.name, kv.value))?;
    }
    let mut orbit = doc.camera;
    if let Some(c) = camera {
        orbit.yaw_deg = c.yaw_deg;
        orbit.pitch_deg = c.pitch_deg;
        orbit.distance = c.distance;
        // The clip range follows the new eye: the project's near plane may lie beyond a
        // close camera's view of the scene and cut its front away.
        match doc.bounds() {
            Some((lo, hi)) => orbit.fit_clip(lo, hi),
            None => orbit.far = orbit.far.max(c.distance * 4.0),
        }
        if let Err((field, detail)) = orbit.check() {
            anyhow::bail!(
                "--camera {c}: it makes camera.{field} invalid: {detail}; give a smaller \
                 DISTANCE"
            );
        }
    }
    Ok((q, orbit))
}

/// The exit status for a command line clap refused: 1 for a bad value (as for every other
/// error the commands report), clap's own otherwise (0 for `--help` and `--version`, 2 for a
/// malformed command line such as an unknown flag or a missing argument).
#[must_use]
pub fn parse_error_exit_code(error: &clap::Error) -> u8 {
    use clap::error::ErrorKind;
    match error.kind() {
        ErrorKind::ValueValidation | ErrorKind::InvalidValue => 1,
        _ => u8::try_from(error.exit_code()).unwrap_or(2),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use thicket_core::quality::KNOB_SPECS;

    #[test]
    fn size_parses_whole_numbers_either_x() {
        let s = |w, h| {
            Ok(ImageSize {
                width: w,
                height: h,
            })
        };
        assert_eq!(ImageSize::parse("1x1"), s(1, 1));
        assert_eq!(ImageSize::parse("800X600"), s(800, 600));
        assert_eq!(ImageSize::parse(" 64 x 48 "), s(64, 48));
        // Empty and oversized images parse: the renderers refuse them with the project named.
        assert_eq!(ImageSize::parse("0x0"), s(0, 0));
        assert_eq!(ImageSize::parse("16385x1"), s(16385, 1));
        assert_eq!(ImageSize::parse("800x600").unwrap().to_string(), "800x600");
    }

    #[test]
    fn size_refuses_what_is_not_two_whole_numbers() {
        assert_eq!(
            ImageSize::parse("12"),
            Err("expected WIDTHxHEIGHT, e.g. 800x600".to_owned())
        );
        assert_eq!(
            ImageSize::parse("-1x10"),
            Err("\"-1\" is not a whole number".to_owned())
        );
        assert_eq!(
            ImageSize::parse("10x2.5"),
            Err("\"2.5\" is not a whole number".to_owned())
        );
        assert!(ImageSize::parse("4294967296x1").is_err());
        assert!(ImageSize::parse("x").is_err());
        assert!(ImageSize::parse("abc").is_err());
    }

    #[test]
    fn camera_parses_three_finite_numbers() {
        assert_eq!(
            CameraArg::parse("35, -15.5,75"),
            Ok(CameraArg {
                yaw_deg: 35.0,
                pitch_deg: -15.5,
                distance: 75.0
            })
        );
        assert_eq!(
            CameraArg::parse("1,2"),
            Err("expected three numbers YAW,PITCH,DISTANCE".to_owned())
        );
        assert!(CameraArg::parse("1,2,3,4").is_err());
        assert_eq!(
            CameraArg::parse("1,a,3"),
            Err("expected YAW,PITCH,DISTANCE numbers".to_owned())
        );
        for bad in ["NaN,0,5", "0,inf,5", "0,0,NaN", "0,0,-inf"] {
            assert_eq!(
                CameraArg::parse(bad),
                Err("YAW, PITCH and DISTANCE must be finite numbers".to_owned()),
                "{bad}"
            );
        }
        assert_eq!(
            CameraArg::parse("0,0,-3"),
            Err("DISTANCE -3 must be above 0".to_owned())
        );
        assert!(CameraArg::parse("0,0,0").is_err());
    }

    #[test]
    fn quality_knobs_are_checked_against_the_table() {
        assert_eq!(
            QualityArg::parse(" lod_pixel_threshold = 2 "),
            Ok(QualityArg {
                name: "lod_pixel_threshold",
                value: "2".to_owned()
            })
        );
        // Every knob in the table parses at a value it accepts: its sweep's first, or a switch.
        for spec in KNOB_SPECS {
            let value = spec.sweep.first().copied().unwrap_or(match spec.kind {
                thicket_core::quality::KnobKind::Bool { .. } => "on",
                thicket_core::quality::KnobKind::StretchStrategy { .. } => "model",
                _ => "1",
            });
            let kv = format!("{}={value}", spec.name);
            assert!(QualityArg::parse(&kv).is_ok(), "{kv}");
        }
        let unknown = QualityArg::parse("nope=1").unwrap_err();
        assert!(unknown.contains("\"nope\""), "{unknown}");
        for spec in KNOB_SPECS {
            assert!(
                unknown.contains(spec.name),
                "lists {}: {unknown}",
                spec.name
            );
        }
        let out_of_range = QualityArg::parse("lod_pixel_threshold=65").unwrap_err();
        assert!(out_of_range.contains("0.05..=64"), "{out_of_range}");
        assert!(QualityArg::parse("lod_pixel_threshold=0.01").is_err());
        assert!(QualityArg::parse("lod_pixel_threshold=NaN").is_err());
        assert!(QualityArg::parse("occlusion_culling=maybe").is_err());
        assert_eq!(
            QualityArg::parse("lod_pixel_threshold"),
            Err("expected KEY=VALUE".to_owned())
        );
    }

    #[test]
    fn knob_values_are_checked_against_the_table() {
        assert_eq!(
            parse_knob_values("shadow_pcf_radius = 0, 2"),
            Ok(KnobValues {
                name: "shadow_pcf_radius".to_owned(),
                values: vec!["0".to_owned(), "2".to_owned()]
            })
        );
        let unknown = parse_knob_values("no_such_knob=1,2").unwrap_err();
        assert!(
            unknown.contains("no_such_knob") && unknown.contains("lod_pixel_threshold"),
            "{unknown}"
        );
        let nan = parse_knob_values("lod_pixel_threshold=1,NaN").unwrap_err();
        assert!(nan.contains("lod_pixel_threshold=NaN"), "{nan}");
        let out_of_range = parse_knob_values("lod_pixel_threshold=1,65").unwrap_err();
        assert!(out_of_range.contains("0.05..=64"), "{out_of_range}");
        for bad in ["lod_pixel_threshold", "=1", "lod_pixel_threshold=1,,2"] {
            let e = parse_knob_values(bad).unwrap_err();
            assert!(e.contains("NAME=V1,V2"), "{bad}: {e}");
        }
    }

    #[test]
    fn overrides_apply_to_the_document_in_order() {
        let doc = Document::default();
        let q = |t: &str| QualityArg::parse(t).unwrap();
        let cam = CameraArg::parse("10,20,30").unwrap();
        let (quality, camera) = view_from(
            &doc,
            &[q("lod_pixel_threshold=2"), q("lod_pixel_threshold=4")],
            Some(cam),
        )
        .unwrap();
        assert!((quality.lod_pixel_threshold - 4.0).abs() < f32::EPSILON);
        assert_eq!(
            (camera.yaw_deg, camera.pitch_deg, camera.distance),
            (10.0, 20.0, 30.0)
        );
        let (quality, camera) = view_from(&doc, &[], None).unwrap();
        assert_eq!(quality, doc.quality);
        assert_eq!(camera, doc.camera);
    }
}
