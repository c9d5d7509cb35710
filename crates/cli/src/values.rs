//! Option values parsed into their types at the edge, as clap value
//! parsers: a bad value is refused by the argument parser (exit 2), its
//! message naming the option and the value, before any command runs.

use alacs::model::MAX_ROUGH_DISTANCE_MM;
use nalgebra::{Isometry3, Point3};

/// Comma-separated finite numbers.
fn numbers(text: &str) -> Result<Vec<f64>, String> {
    text.split(',')
        .map(|item| {
            item.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("`{}` is not a finite number", item.trim()))
        })
        .collect()
}

/// A distance range `MIN,MAX` in mm (`--depth-mm`): positive, ordered and
/// within [`MAX_ROUGH_DISTANCE_MM`].
pub fn distance_range_mm(text: &str) -> Result<(f64, f64), String> {
    match *numbers(text)?.as_slice() {
        [min, max] if 0.0 < min && min <= max && max <= MAX_ROUGH_DISTANCE_MM => Ok((min, max)),
        [_, _] => Err(format!("MIN,MAX must satisfy 0 < MIN <= MAX <= {MAX_ROUGH_DISTANCE_MM} mm")),
        _ => Err("takes MIN,MAX in mm".into()),
    }
}

/// A point `X,Y,Z` in mm (`--rough-mm`), each within +-[`MAX_ROUGH_DISTANCE_MM`].
pub fn point_mm(text: &str) -> Result<Point3<f64>, String> {
    match *numbers(text)?.as_slice() {
        [x, y, z] if [x, y, z].iter().all(|v| v.abs() <= MAX_ROUGH_DISTANCE_MM) => {
            Ok(Point3::new(x, y, z))
        }
        _ => Err(format!("takes X,Y,Z in mm, each within +-{MAX_ROUGH_DISTANCE_MM}")),
    }
}

/// A pose `X,Y,Z,ROLL,PITCH,YAW` (mm, degrees; R = Rz(yaw) Ry(pitch)
/// Rx(roll)): the translation within +-[`MAX_ROUGH_DISTANCE_MM`], the
/// angles within +-360 deg.
pub fn pose(text: &str) -> Result<Isometry3<f64>, String> {
    match *numbers(text)?.as_slice() {
        [x, y, z, ..] if [x, y, z].iter().any(|t| t.abs() > MAX_ROUGH_DISTANCE_MM) => {
            Err(format!("the translation must lie within +-{MAX_ROUGH_DISTANCE_MM} mm"))
        }
        [_, _, _, roll, pitch, yaw] if [roll, pitch, yaw].iter().any(|a| a.abs() > 360.0) => {
            Err("roll, pitch and yaw must lie within +-360 deg".into())
        }
        [x, y, z, roll, pitch, yaw] => Ok(crate::cmd::rig::pose([x, y, z, roll, pitch, yaw])),
        _ => Err("takes X,Y,Z,ROLL,PITCH,YAW (mm, degrees)".into()),
    }
}

/// A checkerboard's inner corners `COLSxROWS` (`--board`, e.g. 9x6), each
/// within [`alacs::model::INNER_CORNERS_RANGE`].
pub fn board_corners(text: &str) -> Result<(usize, usize), String> {
    let parsed = text.split_once(['x', 'X']).and_then(|(c, r)| {
        Some((c.trim().parse::<usize>().ok()?, r.trim().parse::<usize>().ok()?))
    });
    let range = alacs::model::INNER_CORNERS_RANGE;
    match parsed {
        Some((cols, rows)) if range.contains(&cols) && range.contains(&rows) => Ok((cols, rows)),
        Some(_) => Err(format!(
            "a board has {}-{} inner corners along each side",
            range.start(),
            range.end()
        )),
        None => Err("takes COLSxROWS inner corners (e.g. 9x6)".into()),
    }
}

/// A board's square `S` or `X,Y` in mm (`--square-mm`), each within
/// (0, [`alacs::model::MAX_SQUARE_MM`]].
pub fn square_mm(text: &str) -> Result<(f64, f64), String> {
    let (x, y) = match *numbers(text)?.as_slice() {
        [s] => (s, s),
        [x, y] => (x, y),
        _ => return Err("takes S or X,Y in mm".into()),
    };
    let limit = alacs::model::MAX_SQUARE_MM;
    if [x, y].iter().all(|s| *s > 0.0 && *s <= limit) {
        Ok((x, y))
    } else {
        Err(format!("a square must lie in (0, {limit}] mm"))
    }
}

/// One of OpenCV's ArUco dictionary names (`--charuco`, e.g. DICT_5X5_100).
pub fn dictionary(text: &str) -> Result<alacs::model::ArucoDictionary, String> {
    alacs::model::ArucoDictionary::parse(text).map_err(|e| e.to_string())
}

/// A scan mode's name (`--scan-mode`), as rig.toml's `[scan] mode` names it.
pub fn scan_mode(text: &str) -> Result<alacs::rig::ScanModeName, String> {
    alacs::rig::ScanModeName::parse(text)
}

/// A pixel rectangle `u0,v0,u1,v1` (`--roi`, inclusive): whole pixels from
/// 0 (the top-left pixel), u0 <= u1 and v0 <= v1.
pub fn roi(text: &str) -> Result<[u32; 4], String> {
    let values: Vec<u32> =
        text.split(',').map(|v| v.trim().parse::<u32>()).collect::<Result<_, _>>().map_err(
            |_| "takes u0,v0,u1,v1, whole pixels from 0 (the top-left pixel)".to_string(),
        )?;
    match values.as_slice() {
        &[u0, v0, u1, v1] if u0 <= u1 && v0 <= v1 => Ok([u0, v0, u1, v1]),
        _ => Err("takes u0,v0,u1,v1 with u0 <= u1 and v0 <= v1".into()),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn values_parse_into_their_types_or_say_what_they_take() {
        assert_eq!(distance_range_mm("600, 1200").unwrap(), (600.0, 1200.0));
        assert!(distance_range_mm("1200,600").unwrap_err().contains("MIN <= MAX"));
        assert!(distance_range_mm("nan,1").unwrap_err().contains("`nan`"));
        assert_eq!(point_mm("1,2,3").unwrap(), Point3::new(1.0, 2.0, 3.0));
        assert!(point_mm("1,2").is_err() && point_mm("1,2,1e308").is_err());
        let p = pose("10,0,0,0,0,90").unwrap();
        assert!((p * Point3::new(1.0, 0.0, 0.0) - Point3::new(10.0, 1.0, 0.0)).norm() < 1e-9);
        assert!(pose("0,0,0,0,0,400").unwrap_err().contains("360"));
        assert_eq!(roi("0,1,2,3").unwrap(), [0, 1, 2, 3]);
        assert!(roi("-5,0,1,2").unwrap_err().contains("whole pixels"));
        assert!(roi("3,0,1,2").unwrap_err().contains("u0 <= u1"));
        assert_eq!(board_corners("9x6").unwrap(), (9, 6));
        assert!(board_corners("1x8").unwrap_err().contains("inner corners"));
        assert_eq!(square_mm("25").unwrap(), (25.0, 25.0));
        assert!(square_mm("25,nan").is_err() && square_mm("1e308").is_err());
    }
}
