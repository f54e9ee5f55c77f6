//! `PunchCharacter`: the root node of the character scene. In a game it makes the scene physically what
//! training used (joints configured from the core's DOF table, no collisions between its own bodies), and it
//! reads and drives its bodies for `PunchController` with the same core code the training server uses.
//!
//! **A moving character.** A game moves the character (or a parent of it, as it moves a `CharacterBody3D`)
//! every physics frame. The bodies are `top_level`, so Godot's transform propagation never teleports them;
//! instead, every physics frame (`physics_process`, run after the game's own nodes by its priority) the
//! kinematic `Pelvis` (an `AnimatableBody3D`, `sync_to_physics` off) is moved from code to the character's
//! global transform times its rest offset, and the trunk and arms feel that motion through the joints. A move
//! of more than `TELEPORT_DISTANCE_M` or `TELEPORT_TURN_RAD` in one frame (a spawn, a respawn) is a teleport:
//! every body moves with the root at once, keeping its pose, with no velocity.
//!
//! How Jolt moves such a pelvis (Godot 4.6, measured by `tests/godot/moving_character.gd`): setting a kinematic
//! body's transform only sets its target; at the next step Jolt moves it there with `MoveKinematic`, so
//! during that step (and when read after it) the body has the velocity that motion implies (its linear velocity
//! equals the root's displacement times the physics rate, its angular velocity the turn's), and the joints
//! pull the dynamic bodies along within the step, with no jump. Its physics state lags its node by one step, so
//! the pelvis is read from the physics server (`Rig::read_bodies`). Setting the transform of a kinematic body
//! never moves it at once: a teleport switches it to static for the move (placed at once), then back.

use std::cell::Cell;

use glam::Vec3;
use godot::builtin::{Rid, StringName, Transform3D, Vector2, Vector3};
use godot::classes::generic6_dof_joint_3d::{Flag, Param};
use godot::classes::physics_server_3d::{BodyMode, BodyState as ServerBodyState};
use godot::classes::{
    AnimatableBody3D, Generic6DofJoint3D, INode3D, Node, Node3D, PhysicsBody3D, PhysicsDirectBodyState3D,
    PhysicsServer3D, RigidBody3D,
};
use godot::global::{godot_error, godot_warn};
use godot::meta::ToGodot;
use godot::obj::{Base, EngineEnum, Gd, InstanceId, Singleton, WithBaseField};
use godot::prelude::{GodotClass, godot_api};
use punch_core::contract::arm_size::{ARM_SCALE_RANGE, ArmLengths, ArmScale};
use punch_core::contract::character::{Axis, BODY_COUNT, BRACE_TORQUE_SCALE, Body, BodyPart, JOINTS, NECK};
use punch_core::contract::head_size::head_shift_m;
use punch_core::contract::sensing::{BodyState, CharacterGeometry, MAX_BAG_CONTACTS};
use punch_core::rig::transform::{SaidOnce, TransformError};

use crate::arm_sizing::{SceneArms, rebuild_joints};
use crate::convert::{rigid, rotation, vec3, vector3};
use crate::engine_io::{
    character_geometry, drive_joints, enable_motors, joint_axis_settings, neck_axis_settings, scale_motor_torque,
};
use crate::head_sizing::SceneHead;
use crate::punch_controller_registry::PunchControllerRegistry;

/// A move of the character's root larger than this in one physics frame (m) is a teleport (see `PunchCharacter`):
/// 0.5 m is 60 m/s at 120 Hz, far above any walk or lunge.
pub const TELEPORT_DISTANCE_M: f32 = 0.5;
/// A turn of the root larger than this in one physics frame (rad) is a teleport: 45 degrees is 5400 degrees/s.
pub const TELEPORT_TURN_RAD: f32 = std::f32::consts::FRAC_PI_4;
/// `PunchCharacter`'s physics priority: it moves its pelvis after the nodes of default priority (0) have moved it.
const FOLLOW_PRIORITY: i32 = 1000;
/// The largest push `take_hit` accepts (N s): a knock-down of the whole body at about 4 times its mass in N s is
/// far below it; more is a mistake in the game's units.
const MAX_TAKEN_IMPULSE_NS: f32 = 1000.0;

/// A physics-based upper-body character: a kinematic pelvis that follows the node's own transform, a welded
/// head-neck-chest torso, and two arms with 10 actuated degrees of freedom (waist 2, shoulders 3 each, elbows
/// 1 each), driven by joint motors. Use the addon's `punch_character.tscn` rather than building one by hand; a
/// `PunchController` makes it punch.
///
/// Move it (or any parent of it) in `_physics_process`, as a `CharacterBody3D` is moved: every physics frame
/// the pelvis is carried, from code, to where the node now is, and the trunk and arms follow it through their
/// joints, under physics, also while a punch runs. A move of more than 0.5 m or 45 degrees in one physics frame
/// (a spawn, a respawn) is a teleport: the whole body moves at once, keeping its pose, with no velocity.
/// `reset_pose()` puts it back in its guard where it stands.
#[derive(GodotClass)]
#[class(base = Node3D, init)]
pub struct PunchCharacter {
    rig: Option<Rig>,
    /// The arms as the scene had them, captured at the first `size_arms`.
    scene_arms: Option<SceneArms>,
    /// The head as the scene had it, captured at the first `size_head`.
    scene_head: Option<SceneHead>,
    /// How far `size_head` moved the head up its neck from the scene's place, m (0: not moved).
    head_shift_m: f32,
    /// The root transform (without its scale) the pelvis was last carried to (none before `ready`).
    carried_root: Option<Transform3D>,
    /// The node had no usable transform (scale 0, NaN) at `ready`: it is set up at the first physics frame it has one.
    set_up_later: bool,
    /// What was said about the node's transform (each cause once).
    said: SaidOnce,
    /// The bone of a game's own rig that shows each body (`Body::ALL` order; empty for none), told by the
    /// `PunchSkeletonModifier` that poses the rig from this character: `hit_taken` names it.
    rig_bones: [StringName; BODY_COUNT],
    base: Base<Node3D>,
}

/// The character's bodies and joints, found at `ready`.
pub struct Rig {
    /// `Body::ALL` order.
    pub bodies: Vec<Gd<PhysicsBody3D>>,
    pub joint_rids: [Rid; 5],
    /// The bodies' physics-server RIDs (`Body::ALL` order), to recognise their contacts on a target.
    pub body_rids: [Rid; BODY_COUNT],
    /// Each body as a `RigidBody3D` when it is one (`Body::ALL` order), cast once here: a cast every frame
    /// was a measurable part of the controller's per-frame work (BENCHMARKS.md, controller inference).
    rigid: [Option<Gd<RigidBody3D>>; BODY_COUNT],
    /// The physics states of the forearms (`Body::ALL` index, state), to read the fists' contacts.
    pub forearm_states: Vec<(usize, Gd<PhysicsDirectBodyState3D>)>,
    /// The kinematic pelvis's physics state: where the last step put it, with the velocity it moved at.
    pelvis_state: Gd<PhysicsDirectBodyState3D>,
    /// Whether the motors hold with `BRACE_TORQUE_SCALE` times their torque now (`set_braced`).
    braced: Cell<bool>,
    /// Rest-pose geometry (without target data, which the controller adds).
    pub geometry: CharacterGeometry,
    /// Each body's rest transform relative to the character's root (`Body::ALL` order).
    rest_from_root: [Transform3D; BODY_COUNT],
    /// The arms' lengths as the bodies and joints are now.
    pub arm_lengths: ArmLengths,
}

impl Rig {
    /// The rest-pose geometry of the character standing at `root` (its global transform now, without its scale:
    /// `convert::rigid`): where it was built does not matter, so a character moved or turned since `ready` senses in
    /// its own frame.
    pub fn geometry_at(&self, root: Transform3D) -> CharacterGeometry {
        let mut geometry = self.geometry;
        // `root` and the rests are rotations (checked by the caller): the fallback is never taken.
        let turn = |basis| rotation(basis).unwrap_or_default();
        geometry.rest_rotations = std::array::from_fn(|i| turn((root * self.rest_from_root[i]).basis));
        geometry.root_rotation = turn(root.basis);
        geometry.root_position = vec3(root.origin);
        geometry.pelvis_rest_position = vec3((root * self.rest_from_root[Body::Pelvis.index()]).origin);
        geometry
    }

    /// World state of every body, `Body::ALL` order. The dynamic bodies' nodes are read rather than their
    /// physics-server states: a node moved by the game (`reset_pose`) reads its new place at once. The
    /// kinematic pelvis is read from the physics server: its node holds the target of the coming step, its
    /// physics state where the last step put it and the velocity of that move (the root's motion, which the
    /// core's sensing turns into the root's frame and its `root_vel`/`root_spin` features). A body whose transform
    /// or velocity is not a number (physics blew up) is an error naming it.
    pub fn read_bodies(&self) -> Result<[BodyState; BODY_COUNT], String> {
        let mut states = [BodyState::default(); BODY_COUNT];
        for (i, state) in states.iter_mut().enumerate() {
            let (transform, linear, angular) = match &self.rigid[i] {
                Some(rigid) => (
                    self.bodies[i].get_global_transform(),
                    vec3(rigid.get_linear_velocity()),
                    vec3(rigid.get_angular_velocity()),
                ),
                None => (
                    self.pelvis_state.get_transform(),
                    vec3(self.pelvis_state.get_linear_velocity()),
                    vec3(self.pelvis_state.get_angular_velocity()),
                ),
            };
            let bad = |cause: TransformError| format!("the character's body '{}' {cause}", Body::ALL[i].node_name());
            let rotation = rotation(transform.basis).map_err(bad)?;
            let position = vec3(transform.origin);
            if !(position.is_finite() && linear.is_finite() && angular.is_finite()) {
                return Err(bad(TransformError::NotFinite));
            }
            *state = BodyState { position, rotation, linear_velocity: linear, angular_velocity: angular };
        }
        Ok(states)
    }

    /// Puts body `index` (`Body::ALL` order) at `transform` at once, with no velocity. The kinematic pelvis is
    /// switched to static for the move: a kinematic body's new transform is only a target for the next step,
    /// which Jolt would reach by sweeping it (and the arms hanging on it) across the distance.
    pub fn place(&self, index: usize, transform: Transform3D) {
        let mut body = self.bodies[index].clone();
        match &self.rigid[index] {
            Some(rigid) => {
                let mut rigid = rigid.clone();
                rigid.set_global_transform(transform);
                rigid.set_linear_velocity(Vector3::ZERO);
                rigid.set_angular_velocity(Vector3::ZERO);
            }
            None => {
                let mut server = PhysicsServer3D::singleton();
                let rid = body.get_rid();
                server.body_set_mode(rid, BodyMode::STATIC);
                body.set_global_transform(transform);
                server.body_set_state(rid, ServerBodyState::TRANSFORM, &transform.to_variant());
                server.body_set_mode(rid, BodyMode::KINEMATIC);
            }
        }
    }

    /// Sets the joint motors (Godot's 6DOF convention) on actuated axes.
    pub fn drive(&self, motor_velocities: &[Vec3; 5]) {
        drive_joints(&self.joint_rids, motor_velocities);
    }

    /// Turns the joint motors off (`limp`: the body hangs in its joints' limits) or back on.
    pub fn set_limp(&self, limp: bool) {
        enable_motors(&self.joint_rids, !limp);
    }

    /// Braces the joints (`braced`: every motor holds with `BRACE_TORQUE_SCALE` times its torque, a block's guard)
    /// or lets them back to the DOF table's torques; sets the engine only when that changes.
    pub fn set_braced(&self, braced: bool) {
        if self.braced.replace(braced) != braced {
            scale_motor_torque(&self.joint_rids, if braced { BRACE_TORQUE_SCALE } else { 1.0 });
        }
    }
}

#[godot_api]
impl INode3D for PunchCharacter {
    fn ready(&mut self) {
        self.base_mut().set_physics_process_priority(FOLLOW_PRIORITY);
        // A character that pops in from scale 0 (or whose parent does) has no rest to read yet: its bodies are
        // read at the first physics frame it has a size.
        if let Err(cause) = rigid(self.base().get_global_transform()) {
            godot_warn!(
                "PunchCharacter '{}': its transform (or a parent's) {cause} as it enters the scene: it is set up at \
                 the first physics frame it has a usable one",
                self.base().get_name()
            );
            self.set_up_later = true;
            return;
        }
        self.set_up_now();
    }

    fn physics_process(&mut self, _delta: f64) {
        if self.set_up_later && rigid(self.base().get_global_transform()).is_ok() {
            self.set_up_later = false;
            self.set_up_now();
        }
        self.carry_pelvis();
    }
}

#[godot_api]
impl PunchCharacter {
    /// Emitted when the character is struck: by another `PunchController`'s fist (`from` is that controller; the
    /// physics pushed the body already) or by the game's `take_hit` (`from` is null). `part` is `&"head"`, `&"torso"`,
    /// `&"left_arm"` or `&"right_arm"` (the part whose body was struck: the head hangs on its own neck),
    /// `impulse` the push (N s, global axes) and `point` where it struck (global). On a game's own rig (a
    /// `PunchSkeletonModifier` poses it from this character) `bone` names the rig's bone that shows the struck body
    /// (its head, chest, upper arm or forearm bone); empty on the mannequin. The
    /// controller that drives the character has reacted already (`PunchController.react_to_hits`), so a handler
    /// may punch back at once.
    #[signal]
    fn hit_taken(part: StringName, impulse: Vector3, point: Vector3, from: Option<Gd<Node>>, bone: StringName);

    /// Strikes the character as the game's own hit (a kick, a thrown chair, a bullet): `impulse` (N s, global axes;
    /// at most 1,000) pushes `part` (`&"head"`, `&"torso"`, `&"left_arm"` or `&"right_arm"`; the head snaps on its
    /// neck) at `point` (global; the arm's body nearest it takes an arm's push), then
    /// `hit_taken` is emitted and the controller that drives it reacts (`PunchController.react_to_hits`). For scale:
    /// the addon's punches strike a sandbag with 5-10 N s. Returns false, with an error and nothing pushed, for an
    /// unknown part, a vector that is not finite, a larger impulse, or a character that is not ready.
    #[func(gd_self)]
    fn take_hit(mut this: Gd<Self>, part: StringName, impulse: Vector3, point: Vector3) -> bool {
        let pushed = this.bind_mut().push(&part.to_string(), impulse, point);
        match pushed {
            Ok(body) => {
                Self::tell_struck(this, body, impulse, point, None);
                true
            }
            Err(error) => {
                godot_error!("PunchCharacter '{}': take_hit(): {error}; nothing was pushed", this.get_name());
                false
            }
        }
    }

    /// The part (`&"head"`, `&"torso"`, `&"left_arm"`, `&"right_arm"`) `body` is of this character; empty when it is
    /// not one of its bodies.
    #[func]
    fn part_of(&self, body: Option<Gd<Node>>) -> StringName {
        let index =
            body.and_then(|body| self.rig.as_ref()?.bodies.iter().position(|b| b.instance_id() == body.instance_id()));
        index.map_or(StringName::default(), |i| StringName::from(Body::ALL[i].part().name()))
    }

    /// True when the character found all its bodies and joints and configured them.
    #[func]
    fn is_ready_to_punch(&self) -> bool {
        self.rig.is_some()
    }

    /// Puts every body back in its rest (guard) pose where the character now stands, with no velocity: a
    /// fresh start for the next punch. Joint motors are set to rest as well.
    #[func]
    fn reset_pose(&mut self) {
        let Some(rig) = self.rig.as_ref() else {
            godot_error!("PunchCharacter '{}': reset_pose() before the character is ready", self.base().get_name());
            return;
        };
        let root = match rigid(self.base().get_global_transform()) {
            Ok(root) => root,
            Err(cause) => {
                godot_error!(
                    "PunchCharacter '{}': reset_pose(): its transform (or a parent's) {cause}; its pose stays",
                    self.base().get_name()
                );
                return;
            }
        };
        for (i, rest) in rig.rest_from_root.iter().enumerate() {
            rig.place(i, root * *rest);
        }
        rig.drive(&[Vec3::ZERO; 5]);
        self.carried_root = Some(root);
    }

    /// Writes the limits and motors of the core's DOF table into this character's joint nodes, before it is
    /// in a scene tree. The scene builder calls it so the saved scene holds them: each joint is then created
    /// once, in scene order, as in the training server, instead of being rebuilt at `ready` (a rebuild moves
    /// the constraint in Jolt's solve order). Returns false, with an error, if a joint is missing.
    #[func]
    fn store_joint_settings(&mut self) -> bool {
        let base = self.base().clone();
        for (joint_index, joint) in JOINTS.iter().chain([&NECK]).enumerate() {
            match base.get_node_or_null(joint.node_name).and_then(|n| n.try_cast::<Generic6DofJoint3D>().ok()) {
                Some(mut node) => configure_joint(&mut node, joint_index),
                None => {
                    godot_error!("PunchCharacter: missing Generic6DOFJoint3D '{}'", joint.node_name);
                    return false;
                }
            }
        }
        true
    }

    /// Sizes the simulated arms to a character's: `upper_arm_m` from shoulder joint to elbow joint, `forearm_m`
    /// from elbow joint to the fist's centre, `shoulder_width_m` between the two shoulder joints. The bodies,
    /// shapes, fists and joints move (masses stay; inertia follows the length), always from the scene's own
    /// proportions (upper arm 0.282 m, forearm 0.337 m, shoulders 0.36 m apart), and the character is reset to
    /// its guard. The arm (shoulder to fist) must be 0.75 to 1.25 times the scene's and each length 0.65 to 1.35
    /// times; outside that, or before the character is ready, one error says why, the arms keep their size and
    /// this returns false. Call it between punches: `PunchSkeletonModifier` does, with `size_to_rig` on.
    #[func]
    fn size_arms(&mut self, upper_arm_m: f32, forearm_m: f32, shoulder_width_m: f32) -> bool {
        let wanted = ArmLengths { upper_arm_m, forearm_m, shoulder_width_m };
        let result = self.try_size_arms(wanted);
        self.said_if_refused("the arms", result)
    }

    /// The simulated arms' lengths now: (upper arm, elbow to fist centre, shoulder width), m.
    #[func]
    fn arm_lengths(&self) -> Vector3 {
        let lengths = self.rig.as_ref().map(|rig| rig.arm_lengths).unwrap_or(ArmLengths {
            upper_arm_m: 0.0,
            forearm_m: 0.0,
            shoulder_width_m: 0.0,
        });
        Vector3::new(lengths.upper_arm_m, lengths.forearm_m, lengths.shoulder_width_m)
    }

    /// The arm lengths' accepted range for `size_arms` (shoulder to fist centre), as fractions of the scene's.
    #[func]
    fn arm_scale_range() -> Vector2 {
        Vector2::new(ARM_SCALE_RANGE.0, ARM_SCALE_RANGE.1)
    }

    /// A sizing's answer to the game: true when it was done, else false after one error saying why.
    fn said_if_refused(&self, what: &str, result: Result<(), String>) -> bool {
        result
            .map_err(|error| godot_error!("PunchCharacter '{}': cannot size {what}: {error}", self.base().get_name()))
            .is_ok()
    }

    fn try_size_arms(&mut self, wanted: ArmLengths) -> Result<(), String> {
        let rig = self.rig.as_ref().ok_or("the character is not ready")?;
        if self.scene_arms.is_none() {
            let root = self.base().clone().upcast::<Node3D>();
            self.scene_arms = Some(SceneArms::capture(&root, &rig.bodies, &rig.rest_from_root, &rig.geometry)?);
        }
        let scene = self.scene_arms.as_ref().ok_or("no scene arms")?;
        let scale = ArmScale::between(scene.lengths, wanted).map_err(|e| e.to_string())?;
        let root = rigid(self.base().get_global_transform()).map_err(|cause| format!("the character {cause}"))?;
        // The torso, pelvis and head back at rest too: the joints are rebuilt from the bodies' places.
        for i in [Body::Pelvis.index(), Body::Torso.index(), Body::Head.index()] {
            rig.place(i, root * rig.rest_from_root[i]);
        }
        scene.apply(Some(root), scale);
        self.set_up_again(root)
    }

    /// After a sizing moved bodies and joint nodes with every body at rest at `root`: the joints rebuilt from their
    /// places, the rig read again, the motors driving to the guard.
    fn set_up_again(&mut self, root: Transform3D) -> Result<(), String> {
        self.carried_root = Some(root);
        rebuild_joints(&self.base().clone().upcast::<Node3D>())?;
        self.rig = Some(self.set_up()?);
        if let Some(rig) = self.rig.as_ref() {
            rig.drive(&[Vec3::ZERO; 5]);
        }
        Ok(())
    }

    /// Sizes the simulated head to a character's: `shoulder_to_crown_m`, how high its crown stands above the middle
    /// of the two shoulder joints (the scene's: 0.29 m). The head moves along its neck (the neck joint on the chest
    /// stays; the skull keeps its size, mass and inertia), always from the scene's own place, so a fist or
    /// `take_hit` meets the head where the character's is, and the character is reset to its guard. The crown may
    /// stand 0.85 to 1.4 times the scene's height; outside that, or before the character is ready, one error says
    /// why, the head stays and this returns false. Call it between punches: `PunchSkeletonModifier` does, with
    /// `size_head_to_rig` on, from the rig's head.
    #[func]
    fn size_head(&mut self, shoulder_to_crown_m: f32) -> bool {
        let result = self.try_size_head(shoulder_to_crown_m);
        self.said_if_refused("the head", result)
    }

    /// How high the simulated head's crown stands above the middle of the shoulder joints now, m (0 before the
    /// character is ready).
    #[func]
    fn shoulder_to_crown_m(&self) -> f32 {
        let Some(rig) = self.rig.as_ref() else { return 0.0 };
        SceneHead::capture(&self.base().clone().upcast::<Node3D>(), &rig.rest_from_root)
            .map_or(0.0, |head| head.crown_m)
    }

    /// How far `size_head` moved the head up its neck from the scene's place, m (0 before it did; negative: down):
    /// a block's high guard rises as much (`high_guard_rad`).
    pub fn head_shift_m(&self) -> f32 {
        self.head_shift_m
    }

    fn try_size_head(&mut self, shoulder_to_crown_m: f32) -> Result<(), String> {
        let rest_from_root = self.rig.as_ref().ok_or("the character is not ready")?.rest_from_root;
        let root_node = self.base().clone().upcast::<Node3D>();
        if self.scene_head.is_none() {
            self.scene_head = Some(SceneHead::capture(&root_node, &rest_from_root)?);
        }
        let scene = self.scene_head.as_ref().ok_or("no scene head")?;
        let shift_m = head_shift_m(scene.crown_m, shoulder_to_crown_m).map_err(|e| e.to_string())?;
        let root = rigid(self.base().get_global_transform()).map_err(|cause| format!("the character {cause}"))?;
        // Every other body back at rest: the joints are rebuilt from the bodies' places.
        if let Some(rig) = self.rig.as_ref() {
            for (i, rest) in rest_from_root.iter().enumerate().filter(|(i, _)| *i != Body::Head.index()) {
                rig.place(i, root * *rest);
            }
        }
        scene.apply(root, shift_m);
        self.head_shift_m = shift_m;
        self.set_up_again(root)
    }

    /// How much shorter the arm (shoulder to fist centre) is than the scene had it, m (0 before any `size_arms`;
    /// negative: longer): a punch's reach shrinks by it (`ReachVolume::within_arm`).
    pub fn arm_shortfall_m(&self) -> f32 {
        match (&self.scene_arms, &self.rig) {
            (Some(scene), Some(rig)) => scene.lengths.arm_m() - rig.arm_lengths.arm_m(),
            _ => 0.0,
        }
    }

    pub fn rig(&self) -> Option<&Rig> {
        self.rig.as_ref()
    }

    /// The character `body` is a body of, and which.
    fn owner_of(body: &Gd<Node3D>) -> Option<(Gd<Self>, Body)> {
        if !body.is_instance_valid() {
            return None; // freed by a `hit` handler
        }
        let character = body.get_parent()?.try_cast::<Self>().ok()?;
        let index = character.bind().rig.as_ref()?.bodies.iter().position(|b| b.instance_id() == body.instance_id())?;
        Some((character, Body::ALL[index]))
    }

    /// The part of a character `body` is, when it is a body of one.
    pub fn part_of_body(body: &Gd<Node3D>) -> Option<BodyPart> {
        Self::owner_of(body).map(|(_, body)| body.part())
    }

    /// Another controller's fist struck `body` with `impulse` at `point` (both global): when it is a body of a
    /// character, the character is told (`hit_taken`) and its controller reacts.
    pub fn struck_by_fist(body: Gd<Node3D>, impulse: Vector3, point: Vector3, from: InstanceId) {
        if let Some((character, struck)) = Self::owner_of(&body) {
            Self::tell_struck(character, struck, impulse, point, Some(from));
        }
    }

    /// A `PunchSkeletonModifier` poses a game's own rig from this character: the rig's bone that shows each body
    /// (`Body::ALL` order; empty for none), for `hit_taken`.
    pub fn set_rig_bones(&mut self, bones: [StringName; BODY_COUNT]) {
        self.rig_bones = bones;
    }

    /// The reaction first (so that a `hit_taken` handler may punch back), then the signal.
    fn tell_struck(this: Gd<Self>, struck: Body, impulse: Vector3, point: Vector3, from: Option<InstanceId>) {
        if !this.is_instance_valid() {
            return;
        }
        PunchControllerRegistry::react_to_hit(this.instance_id(), from, impulse.length());
        if !this.is_instance_valid() {
            return;
        }
        let from = from.and_then(|id| Gd::<Node>::try_from_instance_id(id).ok());
        let bone = this.bind().rig_bones[struck.index()].clone();
        this.signals().hit_taken().emit(&StringName::from(struck.part().name()), impulse, point, from.as_ref(), &bone);
    }

    /// `take_hit`'s push: the part's body nearest `point` takes `impulse` there.
    fn push(&mut self, part: &str, impulse: Vector3, point: Vector3) -> Result<Body, String> {
        let part = BodyPart::named(part).ok_or_else(|| {
            let names: Vec<&str> = BodyPart::ALL.iter().map(|p| p.name()).collect();
            format!("'{part}' is no part (the parts: {})", names.join(", "))
        })?;
        if !(vec3(impulse).is_finite() && vec3(point).is_finite()) {
            return Err(format!("the impulse {impulse} and the point {point} must be finite"));
        }
        if impulse.length() > MAX_TAKEN_IMPULSE_NS {
            return Err(format!("an impulse of {} N s is more than {MAX_TAKEN_IMPULSE_NS} N s", impulse.length()));
        }
        let rig = self.rig.as_ref().ok_or("the character is not ready")?;
        let distance = |body: &Body| rig.bodies[body.index()].get_global_position().distance_to(point);
        let nearest = part.bodies().iter().min_by(|a, b| distance(a).total_cmp(&distance(b))).ok_or("no body")?;
        let mut rigid_body = rig.rigid[nearest.index()].clone().ok_or("the part's body is not a RigidBody3D")?;
        let offset = point - rigid_body.get_global_position();
        rigid_body.apply_impulse_ex(impulse).position(offset).done();
        Ok(*nearest)
    }

    /// Where the character last stood with a usable transform (its root without the scale; none before it was set
    /// up): while a game holds it at scale 0 or NaN, the body stays and senses there.
    pub fn standing(&self) -> Option<Transform3D> {
        self.carried_root
    }

    fn set_up_now(&mut self) {
        match self.set_up() {
            Ok(rig) => {
                self.rig = Some(rig);
                self.carried_root = rigid(self.base().get_global_transform()).ok();
            }
            Err(error) => godot_error!("PunchCharacter '{}': {error}", self.base().get_name()),
        }
    }

    /// Carries the kinematic pelvis to where the root now is (it moves there in the coming physics step, and the
    /// joints pull the other bodies along), or teleports the whole body when the root jumped. A root with no size,
    /// a NaN or a mirror is not followed (said once per cause): the body waits where it was until it has one.
    fn carry_pelvis(&mut self) {
        let (Some(rig), Some(carried)) = (self.rig.as_ref(), self.carried_root) else { return };
        let root = match rigid(self.base().get_global_transform()) {
            Ok(root) => root,
            Err(cause) => {
                if self.said.first("root", cause) {
                    let what = if cause == TransformError::Mirrored {
                        "; a mirrored body cannot punch: use the other stance (the other hand) instead of a mirrored \
                         model"
                    } else {
                        ""
                    };
                    godot_warn!(
                        "PunchCharacter '{}': its transform (or a parent's) {cause}: its simulated body stays where \
                         it was until the node has a usable transform{what} (said once)",
                        self.base().get_name()
                    );
                }
                return;
            }
        };
        if root == carried {
            return;
        }
        let pelvis = Body::Pelvis.index();
        if is_teleport(carried, root) {
            // Every body keeps its place relative to the root: the pose, moved with it, at rest.
            let moved = root * carried.affine_inverse();
            for i in 0..rig.bodies.len() {
                let place = if i == pelvis {
                    root * rig.rest_from_root[i]
                } else {
                    moved * rig.bodies[i].get_global_transform()
                };
                rig.place(i, place);
            }
        } else {
            rig.bodies[pelvis].clone().set_global_transform(root * rig.rest_from_root[pelvis]);
        }
        self.carried_root = Some(root);
    }

    fn set_up(&mut self) -> Result<Rig, String> {
        let base = self.base().clone();
        let bodies: Vec<Gd<PhysicsBody3D>> = Body::ALL
            .iter()
            .map(|body| {
                base.get_node_or_null(body.node_name()).and_then(|n| n.try_cast::<PhysicsBody3D>().ok()).ok_or_else(
                    || match body {
                        // A character scene saved before the head had its own body.
                        Body::Head => "missing physics body 'Head' (on the 'Neck' joint): build the character scene \
                                       again from the addon's punch_character.tscn"
                            .to_string(),
                        _ => format!("missing physics body '{}'", body.node_name()),
                    },
                )
            })
            .collect::<Result<_, _>>()?;
        let mut joints = Vec::new();
        for (joint_index, joint) in JOINTS.iter().chain([&NECK]).enumerate() {
            let mut node = base
                .get_node_or_null(joint.node_name)
                .and_then(|n| n.try_cast::<Generic6DofJoint3D>().ok())
                .ok_or_else(|| format!("missing Generic6DOFJoint3D '{}'", joint.node_name))?;
            configure_joint(&mut node, joint_index);
            joints.push(node);
        }
        let mut pelvis = bodies[Body::Pelvis.index()].clone().try_cast::<AnimatableBody3D>().map_err(|_| {
            "the 'Pelvis' is not an AnimatableBody3D (the addon's scene has one since the character follows a moving \
             root: use it, or build the scene again)"
                .to_string()
        })?;
        pelvis.set_sync_to_physics(false);
        let mut server = PhysicsServer3D::singleton();
        let pelvis_state =
            server.body_get_direct_state(pelvis.get_rid()).ok_or("the 'Pelvis' has no physics state".to_string())?;
        // The bodies do not follow the root's transform: the pelvis is carried from code, the others by the joints.
        for body in &bodies {
            body.clone().set_as_top_level(true);
        }
        let mut forearm_states = Vec::new();
        for (i, body) in bodies.iter().enumerate() {
            for other in &bodies[i + 1..] {
                body.clone().add_collision_exception_with(other);
            }
            if let Ok(mut rigid) = body.clone().try_cast::<RigidBody3D>() {
                // The controller reads hits from the character's own contacts, whatever the target reports.
                let reported = rigid.get_max_contacts_reported().max(MAX_BAG_CONTACTS as i32);
                rigid.set_max_contacts_reported(reported);
                if [Body::ForearmR, Body::ForearmL].contains(&Body::ALL[i]) {
                    let state = server
                        .body_get_direct_state(rigid.get_rid())
                        .ok_or_else(|| format!("body '{}' has no physics state", rigid.get_name()))?;
                    forearm_states.push((i, state));
                }
            }
        }
        let body_transforms: [Transform3D; BODY_COUNT] = std::array::from_fn(|i| bodies[i].get_global_transform());
        let joint_transforms: [Transform3D; 5] = std::array::from_fn(|j| joints[j].get_global_transform());
        let root_inverse = base.get_global_transform().affine_inverse();
        let geometry = character_geometry(&base, &body_transforms, &joint_transforms, base.get_global_transform())?;
        let at = |j: usize| vec3(joint_transforms[j].origin);
        let fist = vec3(body_transforms[Body::ForearmR.index()] * vector3(geometry.fist_offsets[0]));
        let arm_lengths = ArmLengths {
            upper_arm_m: at(2).distance(at(1)),
            forearm_m: fist.distance(at(2)),
            shoulder_width_m: at(1).distance(at(3)),
        };
        Ok(Rig {
            arm_lengths,
            rigid: std::array::from_fn(|i| bodies[i].clone().try_cast::<RigidBody3D>().ok()),
            joint_rids: std::array::from_fn(|j| joints[j].get_rid()),
            body_rids: std::array::from_fn(|i| bodies[i].get_rid()),
            forearm_states,
            pelvis_state,
            braced: Cell::new(false),
            geometry,
            rest_from_root: std::array::from_fn(|i| root_inverse * body_transforms[i]),
            bodies,
        })
    }
}

/// True when the root moved from `from` to `to` by more than a frame's walk or turn can (`TELEPORT_DISTANCE_M`,
/// `TELEPORT_TURN_RAD`). A transform with no rotation (scale 0, NaN, a mirror) counts as a jump.
pub fn is_teleport(from: Transform3D, to: Transform3D) -> bool {
    let (Ok(a), Ok(b)) = (rotation(from.basis), rotation(to.basis)) else { return true };
    // A NaN origin (not below the limit) is a jump too.
    let moved = (to.origin - from.origin).length();
    moved.is_nan() || moved > TELEPORT_DISTANCE_M || a.angle_between(b) > TELEPORT_TURN_RAD
}

/// Limits and motors of one joint node (`joint_axis_settings`, the same as the training world's joints). Only
/// changed values are set: a limit change rebuilds the engine's constraint, which moves it in Jolt's solve
/// order. The addon's scene already holds these values (`store_joint_settings`), so at `ready` this changes
/// nothing; it matters only for a hand-edited scene. The node's enums have the physics server's values.
/// `joint_index`: of `JOINTS`, or `JOINTS.len()` for the `NECK`.
fn configure_joint(joint: &mut Gd<Generic6DofJoint3D>, joint_index: usize) {
    for axis in Axis::ALL {
        let settings =
            if joint_index < JOINTS.len() { joint_axis_settings(joint_index, axis) } else { neck_axis_settings(axis) };
        for (param, value) in settings.params {
            let param = Param::from_ord(param.ord());
            let current = match axis {
                Axis::X => joint.get_param_x(param),
                Axis::Y => joint.get_param_y(param),
                Axis::Z => joint.get_param_z(param),
            };
            if current != value {
                match axis {
                    Axis::X => joint.set_param_x(param, value),
                    Axis::Y => joint.set_param_y(param, value),
                    Axis::Z => joint.set_param_z(param, value),
                }
            }
        }
        for (flag, enabled) in settings.flags {
            let flag = Flag::from_ord(flag.ord());
            let current = match axis {
                Axis::X => joint.get_flag_x(flag),
                Axis::Y => joint.get_flag_y(flag),
                Axis::Z => joint.get_flag_z(flag),
            };
            if current != enabled {
                match axis {
                    Axis::X => joint.set_flag_x(flag, enabled),
                    Axis::Y => joint.set_flag_y(flag, enabled),
                    Axis::Z => joint.set_flag_z(flag, enabled),
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use godot::builtin::{Basis, Transform3D, Vector3};

    use super::*;

    #[test]
    fn a_frames_walk_or_turn_is_no_teleport_but_a_jump_is() {
        let here = Transform3D::IDENTITY;
        let moved = |turn_rad: f32, x: f32| {
            Transform3D::new(Basis::from_axis_angle(Vector3::UP, turn_rad), Vector3::new(x, 0.0, 0.0))
        };
        assert!(!is_teleport(here, moved(0.05, 0.03)), "a frame of a walk and a turn");
        assert!(is_teleport(here, moved(0.0, TELEPORT_DISTANCE_M + 0.01)));
        assert!(is_teleport(here, moved(TELEPORT_TURN_RAD + 0.01, 0.0)));
        // Under a node scaled by 0.01 (a rig in centimetres), only the motion counts.
        let scaled = Transform3D::new(Basis::IDENTITY.scaled(Vector3::splat(0.01)), Vector3::ZERO);
        assert!(!is_teleport(here, scaled));
    }
}
