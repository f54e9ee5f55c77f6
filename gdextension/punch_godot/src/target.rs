//! What a `PunchController` aims at: any Node3D, and the physics object that stands for it.

use glam::Vec3;
use godot::builtin::Rid;
use godot::classes::{
    Area3D, CharacterBody3D, CollisionObject3D, CylinderShape3D, Node, Node3D, PhysicsDirectBodyState3D,
    PhysicsServer3D, RigidBody3D,
};
use godot::obj::{Gd, Singleton};
use punch_core::contract::sensing::{BodyState, CharacterGeometry};
use punch_core::rig::transform::TransformError;

use crate::convert::{rotation, vec3};

/// What kind of physics object stands for the target, found once when a punch starts (the per-frame reads
/// then need no engine casts).
enum Kind {
    /// Nothing to feel: the policy only aims at the node.
    None,
    /// A RigidBody3D, with its contact list when it reports contacts (as the addon's sandbag does).
    Rigid(Gd<RigidBody3D>, Option<Gd<PhysicsDirectBodyState3D>>),
    Character(Gd<CharacterBody3D>),
    Area(Gd<Area3D>),
    /// A StaticBody3D or another body that does not move by itself.
    Fixed,
}

/// A target node and its physics object: the node itself when it is one (a RigidBody3D, CharacterBody3D,
/// StaticBody3D or Area3D), else a direct child that is one (the sandbag scene's `Bag`), else the nearest
/// ancestor that is one (a marker or bone attachment on an enemy's body). The observation reads the node's
/// position and the object's motion and contacts.
pub struct Target {
    node: Gd<Node3D>,
    body: Option<Gd<CollisionObject3D>>,
    kind: Kind,
    /// Added to the node's position where the policy sees it (a target out of reach is seen at the nearest
    /// point the policy covers), global.
    aim_shift: Vec3,
}

impl Target {
    pub fn resolve(node: Gd<Node3D>) -> Self {
        let as_body = |n: Gd<Node>| n.try_cast::<CollisionObject3D>().ok();
        let body = as_body(node.clone().upcast())
            .or_else(|| node.get_children().iter_shared().find_map(as_body))
            .or_else(|| std::iter::successors(node.get_parent(), |n| n.get_parent()).find_map(as_body));
        let kind = match body.clone() {
            None => Kind::None,
            Some(body) => match body.try_cast::<RigidBody3D>() {
                Ok(rigid) => {
                    let reports = rigid.get_max_contacts_reported() > 0;
                    let contacts = reports.then(|| PhysicsServer3D::singleton().body_get_direct_state(rigid.get_rid()));
                    Kind::Rigid(rigid, contacts.flatten())
                }
                Err(body) => match body.try_cast::<CharacterBody3D>() {
                    Ok(character) => Kind::Character(character),
                    Err(body) => body.try_cast::<Area3D>().map_or(Kind::Fixed, Kind::Area),
                },
            },
        };
        Self { node, body, kind, aim_shift: Vec3::ZERO }
    }

    /// From now on the policy sees the target as if its node were at `point` (global), moving as it moves.
    pub fn aim_at(&mut self, point: Vec3) {
        self.aim_shift = point - vec3(self.node.get_global_position());
    }

    /// Both still exist (a target freed mid-punch ends it).
    pub fn is_valid(&self) -> bool {
        self.node.is_instance_valid() && self.body.as_ref().is_none_or(|b| b.is_instance_valid())
    }

    /// The physics object's RID, for recognising contacts with it.
    pub fn body_rid(&self) -> Option<Rid> {
        self.body.as_ref().map(|b| b.get_rid())
    }

    /// The target's own contact list, when its physics object is a RigidBody3D that reports contacts: the
    /// training server reads the bag's contacts the same way.
    pub fn reported_contacts(&self) -> Option<&Gd<PhysicsDirectBodyState3D>> {
        match &self.kind {
            Kind::Rigid(_, contacts) => contacts.as_ref(),
            _ => None,
        }
    }

    /// The Area3D standing for the target, if it is one (a fist overlaps it rather than touching it).
    pub fn area(&self) -> Option<&Gd<Area3D>> {
        match &self.kind {
            Kind::Area(area) => Some(area),
            _ => None,
        }
    }

    /// The target's state as the policy sees it: the node's pose (shifted by `aim_at`) and its physics
    /// object's velocity (zero for static ones). A position or velocity that is not a number is an error naming the
    /// node; a rotation that cannot be read (the node scaled to 0 or mirrored: only its place matters) is none.
    pub fn state(&self) -> Result<BodyState, String> {
        let transform = self.node.get_global_transform();
        let (linear_velocity, angular_velocity) = match &self.kind {
            Kind::Rigid(rigid, _) => (vec3(rigid.get_linear_velocity()), vec3(rigid.get_angular_velocity())),
            Kind::Character(character) => (vec3(character.get_velocity()), Vec3::ZERO),
            Kind::None | Kind::Area(_) | Kind::Fixed => (Vec3::ZERO, Vec3::ZERO),
        };
        let state = BodyState {
            position: vec3(transform.origin) + self.aim_shift,
            rotation: rotation(transform.basis).unwrap_or_default(),
            linear_velocity,
            angular_velocity,
        };
        if !(state.position.is_finite() && linear_velocity.is_finite() && angular_velocity.is_finite()) {
            return Err(format!(
                "the target '{}' {} (its position or its velocity, or a parent's)",
                self.node.get_name(),
                TransformError::NotFinite
            ));
        }
        Ok(state)
    }

    /// Puts what the observation knows of the target into the character's geometry: a RigidBody3D's mass
    /// (for the momentum-change features) and, when its first shape is a cylinder, its size.
    pub fn describe(&self, geometry: &mut CharacterGeometry) {
        geometry.bag_mass_kg = 0.0;
        let Kind::Rigid(body, _) = &self.kind else { return };
        geometry.bag_mass_kg = body.get_mass();
        let cylinder = body.get_shape_owners().as_slice().first().and_then(|&owner| {
            body.shape_owner_get_shape(owner as u32, 0).and_then(|s| s.try_cast::<CylinderShape3D>().ok())
        });
        if let Some(cylinder) = cylinder {
            geometry.bag_radius_m = cylinder.get_radius();
            geometry.bag_height_m = cylinder.get_height();
        }
    }
}
