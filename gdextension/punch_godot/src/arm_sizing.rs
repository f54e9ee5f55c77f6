//! Applies `punch_core::contract::arm_size` to a `PunchCharacter`'s scene: moves the arm bodies, their shapes, meshes and
//! fist markers, and the shoulder and elbow joints, and rebuilds the joints. Always from the scene as it was
//! loaded (`SceneArms`), so sizing twice does not compound.

use glam::Vec3;
use godot::builtin::{NodePath, PackedVector3Array, Transform3D, Vector3};
use godot::classes::{
    CapsuleMesh, CapsuleShape3D, CollisionShape3D, ConvexPolygonShape3D, Generic6DofJoint3D, MeshInstance3D, Node3D,
    RigidBody3D,
};
use godot::obj::Gd;
use punch_core::contract::arm_size::{ArmLengths, ArmScale, Stretch};
use punch_core::contract::character::{BODY_COUNT, Body, JOINTS, NECK};
use punch_core::contract::sensing::CharacterGeometry;

use crate::convert::{vec3, vector3};

/// One child of an arm body as the scene had it: its local transform and the shape or mesh it held.
struct Part {
    node: Gd<Node3D>,
    transform: Transform3D,
    capsule_shape: Option<Gd<CapsuleShape3D>>,
    convex: Option<Gd<ConvexPolygonShape3D>>,
    capsule_mesh: Option<Gd<CapsuleMesh>>,
}

/// One arm body as the scene had it (relative to the character's root).
struct ArmBody {
    body: Gd<RigidBody3D>,
    rest: Transform3D,
    inertia: Vector3,
    parts: Vec<Part>,
}

/// The arms as the character's scene had them, captured before the first sizing.
pub struct SceneArms {
    /// [right upper arm, right forearm, left upper arm, left forearm].
    bodies: Vec<ArmBody>,
    /// Shoulder and elbow joints: [ShoulderR, ElbowR, ShoulderL, ElbowL] with their transforms relative to root.
    joints: Vec<(Gd<Generic6DofJoint3D>, Transform3D)>,
    /// The fist centres (root frame) and radius.
    fists: [Vec3; 2],
    fist_radius_m: f32,
    pub lengths: ArmLengths,
}

const ARM_BODIES: [Body; 4] = [Body::UpperArmR, Body::ForearmR, Body::UpperArmL, Body::ForearmL];
/// `JOINTS` indices of ShoulderR, ElbowR, ShoulderL, ElbowL.
const ARM_JOINTS: [usize; 4] = [1, 2, 3, 4];

impl SceneArms {
    /// Captures the arms of the scene `root` (the character) whose bodies rest at `rest_from_root`
    /// (`Body::ALL` order) with `geometry` read at the same time.
    pub fn capture(
        root: &Gd<Node3D>,
        bodies: &[Gd<godot::classes::PhysicsBody3D>],
        rest_from_root: &[Transform3D; BODY_COUNT],
        geometry: &CharacterGeometry,
    ) -> Result<SceneArms, String> {
        let mut arm_bodies = Vec::new();
        for body in ARM_BODIES {
            let rigid = bodies[body.index()]
                .clone()
                .try_cast::<RigidBody3D>()
                .map_err(|_| format!("'{}' is not a RigidBody3D", body.node_name()))?;
            let mut parts = Vec::new();
            for child in rigid.get_children().iter_shared() {
                let Ok(node) = child.try_cast::<Node3D>() else { continue };
                let mut part = Part {
                    transform: node.get_transform(),
                    capsule_shape: None,
                    convex: None,
                    capsule_mesh: None,
                    node: node.clone(),
                };
                if let Ok(shape) = node.clone().try_cast::<CollisionShape3D>()
                    && let Some(resource) = shape.get_shape()
                {
                    part.capsule_shape = resource.clone().try_cast::<CapsuleShape3D>().ok();
                    part.convex = resource.try_cast::<ConvexPolygonShape3D>().ok();
                }
                if let Ok(mesh) = node.clone().try_cast::<MeshInstance3D>()
                    && let Some(resource) = mesh.get_mesh()
                {
                    part.capsule_mesh = resource.try_cast::<CapsuleMesh>().ok();
                }
                parts.push(part);
            }
            arm_bodies.push(ArmBody {
                inertia: rigid.get_inertia(),
                rest: rest_from_root[body.index()],
                body: rigid,
                parts,
            });
        }
        let mut joints = Vec::new();
        for j in ARM_JOINTS {
            let name = JOINTS[j].node_name;
            let joint = root
                .get_node_or_null(name)
                .and_then(|n| n.try_cast::<Generic6DofJoint3D>().ok())
                .ok_or_else(|| format!("missing Generic6DOFJoint3D '{name}'"))?;
            // A joint is a child of the root: its transform is relative to the root, in a tree or not.
            let transform = joint.get_transform();
            joints.push((joint, transform));
        }
        let fists = [0, 1].map(|side| {
            let fore = rest_from_root[[Body::ForearmR, Body::ForearmL][side].index()];
            vec3(fore * vector3(geometry.fist_offsets[side]))
        });
        let at = |i: usize| vec3(joints[i].1.origin);
        let lengths = ArmLengths {
            upper_arm_m: at(1).distance(at(0)),
            forearm_m: fists[0].distance(at(1)),
            shoulder_width_m: at(0).distance(at(2)),
        };
        Ok(SceneArms { bodies: arm_bodies, joints, fists, fist_radius_m: geometry.fist_radius_m, lengths })
    }

    /// Sizes the arms to `scale` (from the scene's own) for the character whose root is at `root` (its global
    /// transform now; `None` for a scene outside any tree, whose bodies and joints are placed relative to its
    /// root, as the training server reads it): bodies go to their new rest pose there, with no velocity. The
    /// caller rebuilds the joints (`rebuild_joints`) and reads the geometry again.
    pub fn apply(&self, root: Option<Transform3D>, scale: ArmScale) {
        let mut new_joints = [Transform3D::IDENTITY; 4];
        for side in 0..2 {
            let (shoulder, elbow) = (vec3(self.joints[2 * side].1.origin), vec3(self.joints[2 * side + 1].1.origin));
            let fist = self.fists[side];
            let outward = Vec3::new(shoulder.x.signum(), 0.0, 0.0) * scale.shoulder_shift_m;
            let upper = Stretch {
                origin: shoulder,
                direction: (elbow - shoulder).normalize_or_zero(),
                scale: scale.upper_arm,
                stretched_m: elbow.distance(shoulder),
            };
            let elbow_moved = upper.apply(elbow) - elbow;
            // The fist moves with the forearm's end: only the shaft up to the fist's surface stretches, by as
            // much as brings the fist's centre to `scale.forearm` times its distance from the elbow.
            let fore = Stretch::to_reach(elbow, fist, self.fist_radius_m, scale.forearm);
            let maps: [(&Stretch, Vec3); 2] = [(&upper, outward), (&fore, elbow_moved + outward)];
            for (k, (stretch, shift)) in maps.into_iter().enumerate() {
                let map = |p: Vec3| stretch.apply(p) + shift;
                let arm = &self.bodies[2 * side + k];
                let mut rest = arm.rest;
                rest.origin = vector3(map(vec3(arm.rest.origin)));
                let inverse = rest.affine_inverse();
                let segment_scale = stretch.scale;
                let along = |transform: Transform3D| {
                    (arm.rest * transform).basis.col_b().normalized().dot(vector3(stretch.direction)).abs() > 0.9
                };
                for part in &arm.parts {
                    let mut transform = part.transform;
                    transform.origin = inverse * vector3(map(vec3(arm.rest * part.transform.origin)));
                    let mut node = part.node.clone();
                    node.set_transform(transform);
                    if let Some(shape) = &part.capsule_shape
                        && along(part.transform)
                    {
                        let mut copy = shape.duplicate_resource();
                        copy.set_height(shape.get_height() * segment_scale);
                        node.clone().cast::<CollisionShape3D>().set_shape(&copy);
                    }
                    if let Some(convex) = &part.convex {
                        let mut copy = convex.duplicate_resource();
                        let (old_frame, new_frame) = (arm.rest * part.transform, (rest * transform).affine_inverse());
                        let points: PackedVector3Array = convex
                            .get_points()
                            .as_slice()
                            .iter()
                            .map(|&p| new_frame * vector3(map(vec3(old_frame * p))))
                            .collect();
                        copy.set_points(&points);
                        node.clone().cast::<CollisionShape3D>().set_shape(&copy);
                    }
                    if let Some(mesh) = &part.capsule_mesh
                        && along(part.transform)
                    {
                        let mut copy = mesh.duplicate_resource();
                        copy.set_height(mesh.get_height() * segment_scale);
                        node.clone().cast::<MeshInstance3D>().set_mesh(&copy);
                    }
                }
                // A rod's inertia across its length grows with the length squared; about its own axis it stays.
                let axis = arm.rest.basis.inverse() * vector3(stretch.direction);
                let across = |component: f32, axis_component: f32| {
                    if axis_component.abs() > 0.9 { component } else { component * segment_scale * segment_scale }
                };
                let mut body = arm.body.clone();
                body.set_inertia(Vector3::new(
                    across(arm.inertia.x, axis.x),
                    across(arm.inertia.y, axis.y),
                    across(arm.inertia.z, axis.z),
                ));
                match root {
                    Some(root) => body.set_global_transform(root * rest),
                    None => body.set_transform(rest),
                }
                body.set_linear_velocity(Vector3::ZERO);
                body.set_angular_velocity(Vector3::ZERO);
            }
            let mut shoulder_joint = self.joints[2 * side].1;
            shoulder_joint.origin = vector3(shoulder + outward);
            let mut elbow_joint = self.joints[2 * side + 1].1;
            elbow_joint.origin = vector3(elbow + elbow_moved + outward);
            new_joints[2 * side] = shoulder_joint;
            new_joints[2 * side + 1] = elbow_joint;
        }
        for ((joint, _), transform) in self.joints.iter().zip(new_joints) {
            match root {
                Some(root) => joint.clone().set_global_transform(root * transform),
                None => joint.clone().set_transform(transform),
            }
        }
    }
}

/// Rebuilds every joint of the character, in `JOINTS` order and the `NECK` last (so their order in Jolt's solver
/// is the scene's), from where its bodies and joint nodes are now: a joint's anchors are read from the transforms
/// when it is built, so a joint moved with its bodies must be rebuilt.
pub fn rebuild_joints(root: &Gd<Node3D>) -> Result<(), String> {
    for joint in JOINTS.iter().chain([&NECK]) {
        let mut node = root
            .get_node_or_null(joint.node_name)
            .and_then(|n| n.try_cast::<Generic6DofJoint3D>().ok())
            .ok_or_else(|| format!("missing Generic6DOFJoint3D '{}'", joint.node_name))?;
        let node_b = node.get_node_b();
        node.set_node_b(&NodePath::default());
        node.set_node_b(&node_b);
    }
    Ok(())
}
