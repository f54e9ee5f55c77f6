//! Applies `punch_core::contract::head_size` to a `PunchCharacter`'s scene: moves the head body along its neck and
//! stretches the neck's mesh. Always from the scene as it was loaded (`SceneHead`), so sizing twice does not
//! compound; the caller rebuilds the joints.

use glam::Vec3;
use godot::builtin::{Basis, Transform3D, Vector3};
use godot::classes::{CapsuleShape3D, CollisionShape3D, MeshInstance3D, Node3D, RigidBody3D};
use godot::obj::Gd;
use punch_core::contract::character::{BODY_COUNT, Body, JOINTS};

use crate::convert::vec3;

/// One child of the head body as the scene had it: its local transform.
struct HeadPart {
    node: Gd<Node3D>,
    transform: Transform3D,
}

/// The head as the character's scene had it (relative to the character's root).
pub struct SceneHead {
    body: Gd<RigidBody3D>,
    rest: Transform3D,
    parts: Vec<HeadPart>,
    /// How high the crown (the top of the head's capsule) stands above the middle of the shoulder joints, m.
    pub crown_m: f32,
}

impl SceneHead {
    /// Reads the head of the character `root` as it is now, its body resting at `rest_from_root` (`Body::ALL`
    /// order, root frame).
    pub fn capture(root: &Gd<Node3D>, rest_from_root: &[Transform3D; BODY_COUNT]) -> Result<SceneHead, String> {
        let body = root
            .get_node_or_null(Body::Head.node_name())
            .and_then(|n| n.try_cast::<RigidBody3D>().ok())
            .ok_or("no RigidBody3D 'Head'")?;
        let rest = rest_from_root[Body::Head.index()];
        let joint_at = |name: &str| -> Result<Vec3, String> {
            // A joint is a child of the root: its transform is relative to the root, in a tree or not.
            root.get_node_or_null(name)
                .and_then(|n| n.try_cast::<Node3D>().ok())
                .map(|n| vec3(n.get_transform().origin))
                .ok_or_else(|| format!("missing joint '{name}'"))
        };
        let shoulders = 0.5 * (joint_at(JOINTS[1].node_name)? + joint_at(JOINTS[3].node_name)?);
        let mut parts = Vec::new();
        let mut crown = f32::MIN;
        for child in body.get_children().iter_shared() {
            let Ok(node) = child.try_cast::<Node3D>() else { continue };
            let transform = node.get_transform();
            let capsule = node.clone().try_cast::<CollisionShape3D>().ok().and_then(|shape| shape.get_shape());
            if let Some(capsule) = capsule.and_then(|r| r.try_cast::<CapsuleShape3D>().ok()) {
                // The top of the capsule: its axis's upper end (the axis is its local Y), one radius above.
                let (centre, radius, half) = (rest * transform, capsule.get_radius(), 0.5 * capsule.get_height());
                crown =
                    crown.max(centre.origin.y + centre.basis.col_b().normalized().y.abs() * (half - radius) + radius);
            }
            parts.push(HeadPart { node, transform });
        }
        if crown == f32::MIN {
            return Err("the 'Head' has no capsule shape (the addon's character scene has one)".into());
        }
        Ok(SceneHead { body, rest, parts, crown_m: crown - shoulders.y })
    }

    /// Moves the head `shift_m` up its neck (negative: down) for the character whose root is at `root` (its global
    /// transform now): the body goes to its new rest there, with no velocity,
    /// its shapes as they are; a mesh below the head's centre (the neck's) stretches to span the neck's new length.
    /// The caller rebuilds the joints.
    pub fn apply(&self, root: Transform3D, shift_m: f32) {
        let mut rest = self.rest;
        rest.origin.y += shift_m;
        for part in &self.parts {
            let Ok(mesh) = part.node.clone().try_cast::<MeshInstance3D>() else { continue };
            let height_m = mesh.get_mesh().map_or(0.0, |m| m.get_aabb().size.y);
            if part.transform.origin.y >= 0.0 || height_m <= 0.0 {
                continue;
            }
            // Its top stays where it was on the head, its bottom reaches down to the neck joint again.
            let stretch = (height_m + shift_m) / height_m;
            let mut transform = part.transform;
            transform.basis = part.transform.basis * Basis::from_scale(Vector3::new(1.0, stretch, 1.0));
            transform.origin.y -= 0.5 * shift_m;
            part.node.clone().set_transform(transform);
        }
        let mut body = self.body.clone();
        body.set_global_transform(root * rest);
        body.set_linear_velocity(Vector3::ZERO);
        body.set_angular_velocity(Vector3::ZERO);
    }
}
