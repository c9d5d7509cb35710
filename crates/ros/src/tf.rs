//! The robot's frames as tf2 knows them: the transforms heard on `/tf` and
//! `/tf_static`, the latest of each edge, and lookups between any two
//! frames of one tree (tf2's `lookupTransform` at time zero: the latest
//! transform, no interpolation; the rig stands still while it scans).

use std::collections::HashMap;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

use crate::msgs::TfMessage;

/// Millimetres per metre (tf2 speaks metres; lookups answer in mm).
const MM_PER_M: f64 = 1000.0;

/// Deepest chain of frames a lookup follows: a loop in a broken tree ends
/// here instead of running forever (a robot's tree is a few dozen deep).
const MAX_DEPTH: usize = 256;

/// Most frames kept: a node that hears a misbehaving publisher stays
/// bounded (a robot has hundreds of frames at most).
const MAX_FRAMES: usize = 10_000;

/// The transform tree: each child frame's parent and `parent_from_child`
/// (mm), the latest heard.
#[derive(Debug, Clone, Default)]
pub struct TfTree {
    parent_of: HashMap<String, (String, Isometry3<f64>)>,
}

impl TfTree {
    /// An empty tree.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a `/tf` or `/tf_static` message: each transform replaces the
    /// one of its child frame. Transforms with an empty frame, a child that
    /// is its own parent, or non-finite numbers are skipped.
    pub fn insert(&mut self, message: &TfMessage) {
        for t in &message.transforms {
            let (parent, child) = (t.header.frame_id.trim(), t.child_frame_id.trim());
            let (p, q) = (t.transform.translation, t.transform.rotation);
            let numbers = [p.x, p.y, p.z, q.x, q.y, q.z, q.w];
            let norm = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w).sqrt();
            if parent.is_empty()
                || child.is_empty()
                || parent == child
                || !numbers.iter().all(|v| v.is_finite())
                || norm < 1e-9
                || (self.parent_of.len() >= MAX_FRAMES && !self.parent_of.contains_key(child))
            {
                continue;
            }
            let parent_from_child = Isometry3::from_parts(
                Translation3::new(p.x * MM_PER_M, p.y * MM_PER_M, p.z * MM_PER_M),
                UnitQuaternion::from_quaternion(Quaternion::new(q.w, q.x, q.y, q.z)),
            );
            self.parent_of.insert(child.to_owned(), (parent.to_owned(), parent_from_child));
        }
    }

    /// Adds one transform in mm: `parent_from_child`.
    pub fn insert_mm(&mut self, parent: &str, child: &str, parent_from_child: Isometry3<f64>) {
        self.parent_of.insert(child.to_owned(), (parent.to_owned(), parent_from_child));
    }

    /// `target_from_source` in mm, through the frames both hang from.
    pub fn lookup(&self, target: &str, source: &str) -> Result<Isometry3<f64>, String> {
        if target == source {
            return Ok(Isometry3::identity());
        }
        let up_from_source = self.chain(source)?;
        let up_from_target = self.chain(target)?;
        for (frame, frame_from_target) in &up_from_target {
            if let Some((_, frame_from_source)) = up_from_source.iter().find(|(f, _)| f == frame) {
                return Ok(frame_from_target.inverse() * frame_from_source);
            }
        }
        let root = |chain: &[(String, Isometry3<f64>)]| {
            chain.last().map_or_else(String::new, |(f, _)| f.clone())
        };
        Err(format!(
            "`{source}` and `{target}` are in two trees (roots `{}` and `{}`) on /tf and /tf_static",
            root(&up_from_source),
            root(&up_from_target)
        ))
    }

    /// `frame` and each frame above it with `that_from_frame`, up to the root.
    fn chain(&self, frame: &str) -> Result<Vec<(String, Isometry3<f64>)>, String> {
        let mut chain = vec![(frame.to_owned(), Isometry3::identity())];
        while let Some((parent, parent_from_child)) = self.parent_of.get(&chain[chain.len() - 1].0)
        {
            if chain.len() > MAX_DEPTH || chain.iter().any(|(f, _)| f == parent) {
                return Err(format!("the frames above `{frame}` form a loop on /tf"));
            }
            let parent_from_frame = parent_from_child * chain[chain.len() - 1].1;
            chain.push((parent.clone(), parent_from_frame));
        }
        if chain.len() == 1 && !self.parent_of.values().any(|(p, _)| p == frame) {
            return Err(format!("no transform names the frame `{frame}` on /tf or /tf_static"));
        }
        Ok(chain)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::{Header, Point, Transform, TransformStamped};
    use nalgebra::{Point3, Vector3};
    use ros2_client::builtin_interfaces::Time;

    fn tf(parent: &str, child: &str, t: [f64; 3], q: UnitQuaternion<f64>) -> TransformStamped {
        TransformStamped {
            header: Header::new(Time::ZERO, parent),
            child_frame_id: child.into(),
            transform: Transform {
                translation: Point { x: t[0], y: t[1], z: t[2] },
                rotation: crate::msgs::Quaternion { x: q.i, y: q.j, z: q.k, w: q.w },
            },
        }
    }

    #[test]
    fn lookups_go_through_the_common_ancestor_and_back() {
        // map -> base_link (1 m along x, turned 90 deg about z), base_link ->
        // camera (0.2 m up), map -> tree (2 m along y).
        let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2);
        let mut tree = TfTree::new();
        tree.insert(&TfMessage {
            transforms: vec![
                tf("map", "base_link", [1.0, 0.0, 0.0], turn),
                tf("base_link", "camera", [0.0, 0.0, 0.2], UnitQuaternion::identity()),
                tf("map", "tree", [0.0, 2.0, 0.0], UnitQuaternion::identity()),
            ],
        });
        // A point 1 m ahead of the camera (x of base_link = y of map).
        let map_from_camera = tree.lookup("map", "camera").unwrap();
        let p = map_from_camera * Point3::new(1000.0, 0.0, 0.0);
        assert!((p - Point3::new(1000.0, 1000.0, 200.0)).norm() < 1e-9, "{p}");
        let tree_from_camera = tree.lookup("tree", "camera").unwrap();
        let q = tree_from_camera * Point3::new(1000.0, 0.0, 0.0);
        assert!((q - Point3::new(1000.0, -1000.0, 200.0)).norm() < 1e-9, "{q}");
        let back = tree.lookup("camera", "tree").unwrap() * q;
        assert!((back - Point3::new(1000.0, 0.0, 0.0)).norm() < 1e-9);
        assert_eq!(tree.lookup("camera", "camera").unwrap(), Isometry3::identity());
    }

    #[test]
    fn unknown_frames_other_trees_and_loops_are_named() {
        let mut tree = TfTree::new();
        let id = UnitQuaternion::identity();
        tree.insert(&TfMessage {
            transforms: vec![
                tf("map", "base_link", [0.0; 3], id),
                tf("odom", "wheel", [0.0; 3], id),
                tf("a", "b", [0.0; 3], id),
                tf("b", "a", [0.0; 3], id),
                tf("map", "bad", [f64::NAN, 0.0, 0.0], id),
            ],
        });
        assert!(tree.lookup("map", "gripper").unwrap_err().contains("`gripper`"));
        assert!(tree.lookup("map", "bad").is_err());
        let two = tree.lookup("base_link", "wheel").unwrap_err();
        assert!(two.contains("two trees") && two.contains("`odom`"), "{two}");
        assert!(tree.lookup("map", "a").unwrap_err().contains("loop"));
    }
}
