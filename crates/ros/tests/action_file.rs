//! The Rust types of `alacs_msgs/action/LocalizeFruit` match
//! `ros/alacs_msgs/action/LocalizeFruit.action` field by field: the file is
//! parsed here (types, names, order, the three parts), and each Rust
//! struct's serde fields are compared with it.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use alacs_ros::msgs::{
    Header, LOCALIZE_FRUIT_ACTION, LOCALIZE_FRUIT_FIELDS, LocalizeFruitFeedback, LocalizeFruitGoal,
    LocalizeFruitResult, Point, PointStamped,
};
use ros2_client::builtin_interfaces::Time;

/// The .action file's three parts as (type, name) lists, comments dropped.
fn parse_action(text: &str) -> Vec<Vec<(String, String)>> {
    let mut parts = vec![Vec::new()];
    for line in text.lines() {
        let line = line.split('#').next().unwrap().trim();
        if line.is_empty() {
            continue;
        }
        if line == "---" {
            parts.push(Vec::new());
            continue;
        }
        let mut words = line.split_whitespace();
        let (ty, name) = (words.next().unwrap(), words.next().unwrap());
        assert!(words.next().is_none(), "a default or constant in `{line}`: not expected here");
        parts.last_mut().unwrap().push((ty.to_string(), name.to_string()));
    }
    parts
}

/// A struct's serde field names, in declaration order (serde_json keeps
/// the order a struct serializes its fields in when asked for a string).
fn serde_fields<T: serde::Serialize>(value: &T) -> Vec<String> {
    let text = serde_json::to_string(value).unwrap();
    let map: serde_json::Map<String, serde_json::Value> = serde_json::from_str(&text).unwrap();
    // Order from the text itself: each key's first position.
    let mut keys: Vec<String> = map.keys().cloned().collect();
    keys.sort_by_key(|k| text.find(&format!("\"{k}\":")).unwrap());
    keys
}

#[test]
fn the_rust_action_types_match_the_action_file_field_by_field() {
    let parsed = parse_action(LOCALIZE_FRUIT_ACTION);
    assert_eq!(parsed.len(), 3, "goal, result, feedback");
    for (part, fields) in parsed.iter().zip(LOCALIZE_FRUIT_FIELDS) {
        let expected: Vec<(String, String)> =
            fields.iter().map(|(t, n)| ((*t).to_string(), (*n).to_string())).collect();
        assert_eq!(part, &expected);
    }
    let header = Header { stamp: Time::ZERO, frame_id: String::new() };
    let stamped = PointStamped { header, point: Point::default() };
    let goal = LocalizeFruitGoal { rough_position: stamped.clone(), fruit_radius_m: 0.0 };
    let result = LocalizeFruitResult {
        status: String::new(),
        reason: String::new(),
        position: stamped,
        radius_m: 0.0,
        position_covariance: [0.0; 9],
        selected_frame: 0,
        n_points: 0,
    };
    let feedback =
        LocalizeFruitFeedback { frame: 0, n_frames: 0, slide_position_m: 0.0, stripe_points: 0 };
    let rust = [serde_fields(&goal), serde_fields(&result), serde_fields(&feedback)];
    for (part, names) in parsed.iter().zip(rust) {
        let expected: Vec<String> = part.iter().map(|(_, n)| n.clone()).collect();
        assert_eq!(names, expected);
    }
}
