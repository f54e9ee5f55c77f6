//! The training server's world: N characters and bags built straight on the physics server from templates
//! read once out of the addon's scenes.
//!
//! Why not instance the scenes: for every moving body Godot syncs a node transform each frame, which costs
//! more than Jolt's step itself (a bare 32-character scene: 150,000 character-frames/s as physics-server
//! bodies against 63,000 as nodes). The scenes stay the single source of the data (shapes, masses,
//! joints). A game uses them as nodes through `PunchCharacter`, and both paths share the core's sensing
//! and control.
//!
//! Isolation and determinism: slots live in arenas, each a fresh `World3D` (one physics space) of up to
//! 16 slots. Every slot sits at the arena's origin and is kept apart by collision layers, so each slot
//! computes with the same coordinates. A reset frees everything and builds new arenas, so every episode
//! starts from the same engine state (no warm-start history, the same body order).

use std::collections::HashMap;

use glam::Vec3;
use godot::builtin::{Basis, Rid, Transform3D, Vector3};
use godot::classes::physics_server_3d::{BodyMode, BodyParameter, BodyState as ServerBodyState};
use godot::classes::{
    CollisionShape3D, CylinderShape3D, Generic6DofJoint3D, Node, Node3D, PackedScene, PhysicsBody3D,
    PhysicsDirectBodyState3D, PhysicsServer3D, PinJoint3D, RigidBody3D, Shape3D, World3D,
};
use godot::meta::ToGodot;
use godot::obj::{Gd, NewGd, Singleton};
use punch_core::contract::arm_size::ArmScale;
use punch_core::contract::character::{Axis, BODY_COUNT, Body, JOINTS, JointSpec, NECK};
use punch_core::contract::motion::RootPose;
use punch_core::contract::sensing::{BodyState, CharacterGeometry, FrameReading, MAX_BAG_CONTACTS};
use punch_core::contract::spec::EpisodeConditions;
use punch_core::training::session::World;

use crate::arm_sizing::SceneArms;
use crate::convert::{godot_axis, quat, quaternion, vec3, vector3};
use crate::engine_io::{add_bag_contacts, character_geometry, drive_joints, joint_axis_settings, neck_axis_settings};

/// Most slots per arena: a slot uses two of the 32 collision layers, one for its character and one for its bag.
pub const MAX_SLOTS_PER_WORLD: usize = 16;
/// Contacts the bag reports per step (the trainer reads each fist's impulse on it).
const BAG_MAX_CONTACTS: i32 = MAX_BAG_CONTACTS as i32;

/// One rigid body of a template: where it is relative to its scene's root, its mass properties and shapes.
struct BodyTemplate {
    transform: Transform3D,
    dynamic: bool,
    mass_kg: f32,
    /// Principal moments; zero lets the engine compute them from the shapes.
    inertia: Vector3,
    custom_center_of_mass: Option<Vector3>,
    shapes: Vec<(Gd<Shape3D>, Transform3D)>,
}

impl BodyTemplate {
    fn read(body: &Gd<Node3D>) -> Result<Self, String> {
        let mut shapes = Vec::new();
        for child in body.get_children().iter_shared() {
            if let Ok(collision) = child.try_cast::<CollisionShape3D>() {
                let shape =
                    collision.get_shape().ok_or_else(|| format!("a shape of '{}' is empty", body.get_name()))?;
                shapes.push((shape, collision.get_transform()));
            }
        }
        let rigid = body.clone().try_cast::<RigidBody3D>().ok();
        Ok(Self {
            transform: body.get_transform(),
            dynamic: rigid.is_some(),
            mass_kg: rigid.as_ref().map_or(0.0, |r| r.get_mass()),
            inertia: rigid.as_ref().map_or(Vector3::ZERO, |r| r.get_inertia()),
            custom_center_of_mass: rigid
                .as_ref()
                .filter(|r| r.get_center_of_mass_mode() == godot::classes::rigid_body_3d::CenterOfMassMode::CUSTOM)
                .map(|r| r.get_center_of_mass()),
            shapes,
        })
    }

    /// Creates the body in `space`, placed by `offset` (applied after the template transform). A body that is
    /// not dynamic is kinematic: the pelvis, moved from code with the character's root, and a carried rope.
    fn create(&self, server: &mut Gd<PhysicsServer3D>, space: Rid, offset: Vector3, layer: u32, mask: u32) -> Rid {
        let body = server.body_create();
        server.body_set_mode(body, if self.dynamic { BodyMode::RIGID } else { BodyMode::KINEMATIC });
        for (shape, transform) in &self.shapes {
            server.body_add_shape_ex(body, shape.get_rid()).transform(*transform).done();
        }
        if self.dynamic {
            server.body_set_param(body, BodyParameter::MASS, &self.mass_kg.to_variant());
            if self.inertia != Vector3::ZERO {
                server.body_set_param(body, BodyParameter::INERTIA, &self.inertia.to_variant());
            }
            if let Some(center) = self.custom_center_of_mass {
                server.body_set_param(body, BodyParameter::CENTER_OF_MASS, &center.to_variant());
            }
            server.body_set_state(body, ServerBodyState::CAN_SLEEP, &false.to_variant());
        }
        server.body_set_collision_layer(body, layer);
        server.body_set_collision_mask(body, mask);
        let mut transform = self.transform;
        transform.origin += offset;
        server.body_set_state(body, ServerBodyState::TRANSFORM, &transform.to_variant());
        server.body_set_space(body, space);
        body
    }
}

/// The character scene, read once.
struct CharacterTemplate {
    /// `Body::ALL` order.
    bodies: Vec<BodyTemplate>,
    /// Joint frames in the parent's and the child's local coordinates, `JOINTS` order, then the `NECK`'s.
    joint_frames: Vec<(Transform3D, Transform3D)>,
    geometry: CharacterGeometry,
}

/// The sandbag scene, read once.
struct BagTemplate {
    body: BodyTemplate,
    /// Pin point in the bag's local coordinates, and relative to the scene root (the bag's centre of mass).
    pin_local: Vector3,
    pin_from_root: Vector3,
    radius_m: f32,
    height_m: f32,
}

fn instantiate_3d(scene: &Gd<PackedScene>, what: &str) -> Result<Gd<Node3D>, String> {
    scene
        .instantiate()
        .and_then(|n| n.try_cast::<Node3D>().ok())
        .ok_or_else(|| format!("the {what} scene's root is not a Node3D"))
}

fn child_3d(root: &Gd<Node3D>, path: &str) -> Result<Gd<Node3D>, String> {
    root.get_node_or_null(path)
        .and_then(|n| n.try_cast::<Node3D>().ok())
        .ok_or_else(|| format!("missing node '{path}'"))
}

impl CharacterTemplate {
    /// The scene with its arms sized by `arms` (`ArmScale::IDENTITY`: as the scene has them), sized as
    /// `PunchCharacter.size_arms` sizes a game's character, within the range it accepts.
    fn read(scene: &Gd<PackedScene>, arms: ArmScale) -> Result<Self, String> {
        let root = instantiate_3d(scene, "character")?;
        let result = (|| {
            let own = Self::read_nodes(&root)?;
            if arms == ArmScale::IDENTITY {
                return Ok(own);
            }
            let bodies: Vec<Gd<PhysicsBody3D>> = Body::ALL
                .iter()
                .map(|b| child_3d(&root, b.node_name())?.try_cast::<PhysicsBody3D>().map_err(|_| "not a body".into()))
                .collect::<Result<_, String>>()?;
            let rest: [Transform3D; BODY_COUNT] = std::array::from_fn(|i| own.bodies[i].transform);
            let scene_arms = SceneArms::capture(&root, &bodies, &rest, &own.geometry)?;
            ArmScale::between(scene_arms.lengths, arms.lengths(scene_arms.lengths)).map_err(|e| e.to_string())?;
            scene_arms.apply(None, arms);
            Self::read_nodes(&root)
        })();
        root.upcast::<Node>().free();
        result
    }

    fn read_nodes(root: &Gd<Node3D>) -> Result<Self, String> {
        let body_nodes: Vec<Gd<Node3D>> =
            Body::ALL.iter().map(|b| child_3d(root, b.node_name())).collect::<Result<_, _>>()?;
        let bodies: Vec<BodyTemplate> = body_nodes.iter().map(BodyTemplate::read).collect::<Result<_, _>>()?;
        let mut joint_frames = Vec::new();
        let mut joint_transforms = Vec::new();
        for joint in JOINTS.iter().chain([&NECK]) {
            let node = child_3d(root, joint.node_name)?;
            node.clone()
                .try_cast::<Generic6DofJoint3D>()
                .map_err(|_| format!("'{}' is not a Generic6DOFJoint3D", joint.node_name))?;
            let at = node.get_transform();
            let parent = bodies[joint.parent.index()].transform;
            let child = bodies[joint.child.index()].transform;
            joint_frames.push((parent.affine_inverse() * at, child.affine_inverse() * at));
            joint_transforms.push(at);
        }
        // The template's frame is the scene root's, so the root sits at the identity.
        let body_transforms: [Transform3D; BODY_COUNT] = std::array::from_fn(|i| bodies[i].transform);
        let joint_transforms: [Transform3D; 5] = std::array::from_fn(|j| joint_transforms[j]);
        let geometry = character_geometry(root, &body_transforms, &joint_transforms, Transform3D::IDENTITY)?;
        Ok(Self { bodies, joint_frames, geometry })
    }
}

impl BagTemplate {
    fn read(scene: &Gd<PackedScene>) -> Result<Self, String> {
        let root = instantiate_3d(scene, "sandbag")?;
        let result = (|| {
            let bag = child_3d(&root, "Bag")?;
            let body = BodyTemplate::read(&bag)?;
            let cylinder = body
                .shapes
                .first()
                .and_then(|(s, _)| s.clone().try_cast::<CylinderShape3D>().ok())
                .ok_or("the bag's first shape is not a CylinderShape3D")?;
            let hook = root
                .get_node_or_null("Hook")
                .and_then(|n| n.try_cast::<PinJoint3D>().ok())
                .ok_or("the sandbag scene has no PinJoint3D 'Hook'")?;
            let pin_from_root = hook.get_position();
            Ok(Self {
                pin_local: body.transform.affine_inverse() * pin_from_root,
                pin_from_root,
                radius_m: cylinder.get_radius(),
                height_m: cylinder.get_height(),
                body,
            })
        })();
        root.upcast::<Node>().free();
        result
    }
}

/// One slot's engine objects.
struct Slot {
    /// `Body::ALL` order (the pelvis is kinematic).
    bodies: [Rid; BODY_COUNT],
    states: Vec<Gd<PhysicsDirectBodyState3D>>,
    joints: [Rid; 5],
    neck: Rid,
    bag: Rid,
    bag_state: Gd<PhysicsDirectBodyState3D>,
    pin: Rid,
    /// The kinematic body a carried bag's rope hangs from (`EpisodeConditions::glides`, `rides`); none for a fixed rope.
    rope_anchor: Option<Rid>,
    /// Where the placement put the bag (its offset from the template's place).
    bag_offset: Vector3,
    /// The kinematic pelvis's linear and angular velocity as last moved (the engine reports a kinematic body's
    /// velocity only once it has stepped).
    pelvis_velocity: (Vec3, Vec3),
    geometry: CharacterGeometry,
}

/// Most sized character templates kept (training draws arm sizes on a grid: `ArmRange` in the trainer).
const MAX_SIZED_TEMPLATES: usize = 1024;

/// The key of a sized template: the scale's exact values.
fn size_key(arms: &ArmScale) -> [u32; 3] {
    [arms.upper_arm.to_bits(), arms.forearm.to_bits(), arms.shoulder_shift_m.to_bits()]
}

/// The `World` the session drives.
pub struct TrainingWorld {
    character_scene: Gd<PackedScene>,
    /// The character as its scene has it.
    character: CharacterTemplate,
    /// The character with other arm sizes, built when a placement first asks for one.
    sized: HashMap<[u32; 3], CharacterTemplate>,
    bag: BagTemplate,
    slot_count: usize,
    slots_per_world: usize,
    arenas: Vec<Gd<World3D>>,
    slots: Vec<Slot>,
}

impl TrainingWorld {
    /// `slots_per_world` characters share one physics world (1 ..= 16). Within a shared world, Jolt orders
    /// the contacts of two bodies touching the bag at once by body ids, so such a punch can differ in the last
    /// bits from slot to slot; with 1 every slot is bitwise identical, at about 2.7 times the cost.
    pub fn new(
        character_scene: &Gd<PackedScene>,
        sandbag_scene: &Gd<PackedScene>,
        slot_count: usize,
        slots_per_world: usize,
    ) -> Result<Self, String> {
        Ok(Self {
            character_scene: character_scene.clone(),
            character: CharacterTemplate::read(character_scene, ArmScale::IDENTITY)?,
            sized: HashMap::new(),
            bag: BagTemplate::read(sandbag_scene)?,
            slot_count,
            slots_per_world: slots_per_world.clamp(1, MAX_SLOTS_PER_WORLD),
            arenas: Vec::new(),
            slots: Vec::new(),
        })
    }

    fn free_all(&mut self) {
        let mut server = PhysicsServer3D::singleton();
        for slot in self.slots.drain(..) {
            let joints = slot.joints.into_iter().chain([slot.neck, slot.pin]);
            for rid in joints.chain(slot.bodies).chain([slot.bag]).chain(slot.rope_anchor) {
                server.free_rid(rid);
            }
        }
        // Dropping the worlds frees their physics spaces.
        self.arenas.clear();
    }

    /// Builds the sized templates `placements` ask for and has not got. Call with no slot built: forgetting a
    /// template frees its shapes.
    fn prepare_sizes(&mut self, placements: &[EpisodeConditions]) -> Result<(), String> {
        let wanted: Vec<ArmScale> = placements.iter().map(|p| p.arms).filter(|a| *a != ArmScale::IDENTITY).collect();
        let missing = wanted.iter().filter(|a| !self.sized.contains_key(&size_key(a))).count();
        if self.sized.len() + missing > MAX_SIZED_TEMPLATES {
            let keep: Vec<[u32; 3]> = wanted.iter().map(size_key).collect();
            self.sized.retain(|key, _| keep.contains(key));
        }
        for arms in wanted {
            if !self.sized.contains_key(&size_key(&arms)) {
                let template = CharacterTemplate::read(&self.character_scene, arms)
                    .map_err(|e| format!("cannot size the arms: {e}"))?;
                self.sized.insert(size_key(&arms), template);
            }
        }
        Ok(())
    }

    fn template(&self, arms: &ArmScale) -> &CharacterTemplate {
        self.sized.get(&size_key(arms)).unwrap_or(&self.character)
    }

    fn build_slot(
        &self,
        server: &mut Gd<PhysicsServer3D>,
        space: Rid,
        slot: usize,
        placement: &EpisodeConditions,
    ) -> Slot {
        let character = self.template(&placement.arms);
        // The character's bodies are on one layer and mask only its bag's layer, and the bag the other way
        // round: the character never collides with itself, the bag with all of it, and masks stay two-sided
        // (under Jolt a body that does not mask the other acts as immovable to it).
        let character_layer = 1u32 << (2 * (slot % self.slots_per_world));
        let bag_layer = character_layer << 1;
        let bodies: [Rid; BODY_COUNT] = std::array::from_fn(|i| {
            character.bodies[i].create(server, space, Vector3::ZERO, character_layer, bag_layer)
        });
        // The joints in the scene's order (the game creates them so): `JOINTS`, then the neck.
        let mut make_joint = |j: usize, spec: &JointSpec| {
            let joint = server.joint_create();
            let (frame_a, frame_b) = character.joint_frames[j];
            server.joint_make_generic_6dof(
                joint,
                bodies[spec.parent.index()],
                frame_a,
                bodies[spec.child.index()],
                frame_b,
            );
            server.joint_disable_collisions_between_bodies(joint, true);
            configure_server_joint(server, joint, j);
            joint
        };
        let joints: [Rid; 5] = std::array::from_fn(|j| make_joint(j, &JOINTS[j]));
        let neck = make_joint(JOINTS.len(), &NECK);
        let offset = Vector3::new(placement.side_m, placement.height_m, placement.distance_m);
        let bag = self.bag.body.create(server, space, offset, bag_layer, character_layer);
        server.body_set_max_contacts_reported(bag, BAG_MAX_CONTACTS);
        let pin = server.joint_create();
        let rope_anchor = (placement.glides || placement.rides).then(|| {
            // A shapeless kinematic body at the rope's top, moved every frame (`move_rope`).
            let anchor = server.body_create();
            server.body_set_mode(anchor, BodyMode::KINEMATIC);
            server.body_set_collision_layer(anchor, 0);
            server.body_set_collision_mask(anchor, 0);
            let at = Transform3D::IDENTITY.translated(self.bag.pin_from_root + offset);
            server.body_set_state(anchor, ServerBodyState::TRANSFORM, &at.to_variant());
            server.body_set_space(anchor, space);
            server.body_set_state(
                anchor,
                ServerBodyState::LINEAR_VELOCITY,
                &vector3(placement.velocity()).to_variant(),
            );
            anchor
        });
        match rope_anchor {
            Some(anchor) => server.joint_make_pin(pin, bag, self.bag.pin_local, anchor, Vector3::ZERO),
            None => server.joint_make_pin(pin, bag, self.bag.pin_local, Rid::Invalid, self.bag.pin_from_root + offset),
        }
        self.set_bag_motion(server, bag, placement);

        let state = |server: &mut Gd<PhysicsServer3D>, rid: Rid| server.body_get_direct_state(rid);
        let states = bodies.iter().filter_map(|&rid| state(server, rid)).collect();
        let bag_state = state(server, bag).expect("a rigid body has a direct state");
        let mut geometry = character.geometry;
        geometry.bag_radius_m = self.bag.radius_m;
        geometry.bag_height_m = self.bag.height_m;
        geometry.bag_mass_kg = self.bag.body.mass_kg;
        Slot {
            bodies,
            states,
            joints,
            neck,
            bag,
            bag_state,
            pin,
            rope_anchor,
            bag_offset: offset,
            pelvis_velocity: (Vec3::ZERO, Vec3::ZERO),
            geometry,
        }
    }
}

impl TrainingWorld {
    /// Sets a bag's velocity from its placement: a bag swinging on its rope turns about the pin as it moves,
    /// ω = r × v / |r|² (r from the pin to the centre of mass).
    /// A gliding bag (its rope carried) moves along without turning.
    fn set_bag_motion(&self, server: &mut Gd<PhysicsServer3D>, bag: Rid, placement: &EpisodeConditions) {
        let velocity = vector3(placement.velocity());
        let arm = self.bag.body.transform.origin - self.bag.pin_from_root;
        let spin = if placement.glides { Vector3::ZERO } else { arm.cross(velocity) / arm.length_squared() };
        server.body_set_state(bag, ServerBodyState::LINEAR_VELOCITY, &velocity.to_variant());
        server.body_set_state(bag, ServerBodyState::ANGULAR_VELOCITY, &spin.to_variant());
    }
}

impl Drop for TrainingWorld {
    fn drop(&mut self) {
        self.free_all();
    }
}

/// Limits and motors of a server joint (`joint_axis_settings`): `joint_index` of `JOINTS`, or `JOINTS.len()` for
/// the neck (`neck_axis_settings`).
fn configure_server_joint(server: &mut Gd<PhysicsServer3D>, joint: Rid, joint_index: usize) {
    for axis in Axis::ALL {
        let settings =
            if joint_index < JOINTS.len() { joint_axis_settings(joint_index, axis) } else { neck_axis_settings(axis) };
        for (param, value) in settings.params {
            server.generic_6dof_joint_set_param(joint, godot_axis(axis), param, value);
        }
        for (flag, enabled) in settings.flags {
            server.generic_6dof_joint_set_flag(joint, godot_axis(axis), flag, enabled);
        }
    }
}

impl World for TrainingWorld {
    fn slot_count(&self) -> usize {
        self.slot_count
    }

    fn reset(&mut self, placements: &[EpisodeConditions]) -> Result<(), String> {
        self.free_all();
        self.prepare_sizes(placements)?;
        let mut server = PhysicsServer3D::singleton();
        for first in (0..self.slot_count).step_by(self.slots_per_world) {
            let arena = World3D::new_gd();
            let space = arena.get_space();
            let end = (first + self.slots_per_world).min(self.slot_count);
            for (slot, placement) in placements.iter().enumerate().take(end).skip(first) {
                let built = self.build_slot(&mut server, space, slot, placement);
                self.slots.push(built);
            }
            self.arenas.push(arena);
        }
        if self.slots.iter().any(|s| s.states.len() != BODY_COUNT) {
            return Err("a body of the character has no direct state".into());
        }
        Ok(())
    }

    fn place_bag(&mut self, slot: usize, placement: &EpisodeConditions) {
        let mut server = PhysicsServer3D::singleton();
        let Some((bag, rope_anchor)) = self.slots.get(slot).map(|s| (s.bag, s.rope_anchor)) else { return };
        let offset = Vector3::new(placement.side_m, placement.height_m, placement.distance_m);
        let mut transform = self.bag.body.transform;
        transform.origin += offset;
        server.body_set_state(bag, ServerBodyState::TRANSFORM, &transform.to_variant());
        if let Some(anchor) = rope_anchor {
            let at = Transform3D::IDENTITY.translated(self.bag.pin_from_root + offset);
            server.body_set_state(anchor, ServerBodyState::TRANSFORM, &at.to_variant());
        }
        self.slots[slot].bag_offset = offset;
        self.set_bag_motion(&mut server, bag, placement);
    }

    fn geometry(&self, slot: usize) -> CharacterGeometry {
        self.slots[slot].geometry
    }

    fn read(&self, slot: usize) -> FrameReading {
        let slot = &self.slots[slot];
        let mut bodies = [BodyState::default(); BODY_COUNT];
        for (body, state) in bodies.iter_mut().zip(&slot.states) {
            *body = read_state(state);
        }
        let pelvis = &mut bodies[Body::Pelvis.index()];
        (pelvis.linear_velocity, pelvis.angular_velocity) = slot.pelvis_velocity;
        let mut reading = FrameReading { bodies, bag: read_state(&slot.bag_state), ..FrameReading::default() };
        add_bag_contacts(&slot.bag_state, &slot.bodies, &mut reading);
        reading
    }

    fn drive(&mut self, slot: usize, motor_velocities: &[Vec3; 5]) {
        drive_joints(&self.slots[slot].joints, motor_velocities);
    }

    fn move_pelvis(&mut self, slot: usize, root: &RootPose) {
        let pelvis = self.slots[slot].bodies[Body::Pelvis.index()];
        let rest = self.character.bodies[Body::Pelvis.index()].transform;
        let carried =
            Transform3D::new(Basis::from_quaternion(quaternion(root.rotation)), vector3(root.position)) * rest;
        // Jolt moves a kinematic body to its set transform over the next step (`MoveKinematic`), with the velocity
        // that takes; setting its velocity instead would set a surface velocity, a conveyor belt for contacts.
        PhysicsServer3D::singleton().body_set_state(pelvis, ServerBodyState::TRANSFORM, &carried.to_variant());
        self.slots[slot].pelvis_velocity = (root.velocity_at(vec3(carried.origin)), root.angular_velocity);
    }

    fn carry_bodies(&mut self, slot_index: usize, root: &RootPose, with_bag: bool) {
        let mut server = PhysicsServer3D::singleton();
        let slot = &self.slots[slot_index];
        let pelvis = vec3(slot.states[Body::Pelvis.index()].get_transform().origin);
        let pelvis_velocity = (root.velocity_at(pelvis), root.angular_velocity);
        for (body, state) in slot.bodies.iter().zip(&slot.states).skip(1) {
            let carried = root.velocity_at(vec3(state.get_transform().origin));
            let velocity = state.get_linear_velocity() + vector3(carried);
            let spin = state.get_angular_velocity() + vector3(root.angular_velocity);
            server.body_set_state(*body, ServerBodyState::LINEAR_VELOCITY, &velocity.to_variant());
            server.body_set_state(*body, ServerBodyState::ANGULAR_VELOCITY, &spin.to_variant());
        }
        if with_bag {
            let carried = root.velocity_at(vec3(slot.bag_state.get_transform().origin));
            let velocity = slot.bag_state.get_linear_velocity() + vector3(carried);
            let spin = slot.bag_state.get_angular_velocity() + vector3(root.angular_velocity);
            server.body_set_state(slot.bag, ServerBodyState::LINEAR_VELOCITY, &velocity.to_variant());
            server.body_set_state(slot.bag, ServerBodyState::ANGULAR_VELOCITY, &spin.to_variant());
        }
        self.slots[slot_index].pelvis_velocity = pelvis_velocity;
    }

    fn move_rope(&mut self, slot: usize, carry: &RootPose) {
        let Some(anchor) = self.slots[slot].rope_anchor else { return };
        let start = vec3(self.bag.pin_from_root + self.slots[slot].bag_offset);
        let at = Transform3D::IDENTITY.translated(vector3(carry.position + carry.rotation * start));
        PhysicsServer3D::singleton().body_set_state(anchor, ServerBodyState::TRANSFORM, &at.to_variant());
    }
}

/// A body's state from its physics-server direct state.
fn read_state(state: &Gd<PhysicsDirectBodyState3D>) -> BodyState {
    let transform = state.get_transform();
    BodyState {
        position: vec3(transform.origin),
        rotation: quat(transform.basis.get_quaternion()),
        linear_velocity: vec3(state.get_linear_velocity()),
        angular_velocity: vec3(state.get_angular_velocity()),
    }
}
