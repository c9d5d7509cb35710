//! The `alacs detect --json` object (docs/FORMATS.md, "alacs detect"):
//! written here and nowhere else.

use serde_json::{Value, json};

use crate::Detection;

/// `{"detections": [...]}`, one object per detection in the given order:
/// `bbox_px`, `centre_px`, `radius_px`, `score`, and with a rough position
/// `position_mm`, `radius_mm`, `position_cov_mm2` (3 x 3, rows),
/// `depth_pixels`.
pub fn detections_json(detections: &[Detection]) -> Value {
    let items: Vec<Value> = detections
        .iter()
        .map(|d| {
            let mut item = json!({
                "bbox_px": d.bbox_px(),
                "centre_px": [d.centre_px.x, d.centre_px.y],
                "radius_px": d.radius_px,
                "score": d.score,
            });
            if let (Some(rough), Some(object)) = (&d.rough, item.as_object_mut()) {
                let p = rough.position_mm;
                let c = rough.position_cov_mm2;
                let rows: Vec<[f64; 3]> =
                    (0..3).map(|r| [c[(r, 0)], c[(r, 1)], c[(r, 2)]]).collect();
                object.insert("position_mm".into(), json!([p.x, p.y, p.z]));
                object.insert("radius_mm".into(), json!(rough.radius_mm));
                object.insert("position_cov_mm2".into(), json!(rows));
                object.insert("depth_pixels".into(), json!(rough.depth_pixels));
            }
            item
        })
        .collect();
    json!({ "detections": items })
}
