//! `PunchSkeletonModifier`: puts a `PunchController`'s simulated upper body onto a game's own rigged
//! `Skeleton3D`, after its animation, blended in and out around punches.
//!
//! Method (the math is `punch_core::rig::skeleton_pose`, unit-tested there):
//! - Mapping: `punch_core::rig::bone_map` finds the hips, the spine up to the chest, the head and per side the
//!   clavicle, upper arm, forearm and hand from bone names and parents (Godot humanoid profile, Mixamo, Unreal,
//!   CMU, MakeHuman, Blender namings); bones typed into `bone_map` by hand hold their roles.
//! - Rest frames are read from the skeleton's global rest, never assumed: a bone's direction is the line from
//!   its head to its child's, and the rig's left, up and front come from its upper arms, hips and head. Each
//!   segment gets an anatomical frame (its direction, and the side its elbow folds to, which is the front for
//!   the straight arms of a T- or A-pose); the simulated bodies get the same frames from the character's
//!   geometry. A bone's global rotation is the simulated segment's frame now times the bone's rest frame's
//!   inverse times the bone's rest rotation: it points along the segment and turns about itself as the segment
//!   does, whatever axis convention (+Y, +X, any roll) the rig uses.
//! - The chest takes the simulated torso's rotation, shared evenly along the spine; the clavicles, twist bones
//!   on the arm and the hand follow their segment rigidly, as at rest. With `fist_curl`, the fingers below each
//!   hand close into a fist (`punch_core::rig::fist`: each finger bone bends toward the palm about an axis read from
//!   the rest). The neck and head keep the animation's pose on the chest, turned by the simulated head's snap on
//!   its neck (a hit). Hips and legs keep the animation's pose. Only rotations are written
//!   (`set_bone_pose_rotation`), so the rig keeps its own bone lengths.
//! - Blending: each written bone's local rotation (the fingers' included) is `slerp(animation, simulated, w)`;
//!   `w` eases from 0 to 1 over `blend_in_s` when a punch (or the recovery after it) starts and back over
//!   `blend_out_s` when it is over (smoothstep: no step in the weight nor its rate). With `guard_source`
//!   Controller, `w` stays 1 and the guard between punches is the simulated one.
//! - The spine bends about other points than the simulated waist joint, so the spine's first bone is shifted
//!   (by the blend weight's share) until the rig's shoulders sit on the simulated ones.
//! - Placing: with `follow_rig`, the simulated character's root is kept, every frame and also while it punches,
//!   where it faces the rig's front with its shoulder joints' midpoint on the rig's (rest upper-arm heads under
//!   the skeleton's transform). Its kinematic pelvis follows the root under physics (`PunchCharacter`), so a rig
//!   that walks or turns carries the simulated body along, and the pose written back stays on the rig: the pose
//!   math reads the bodies' rotations in the skeleton's space and needs no root of its own. A placement that
//!   jumps (a teleport: more than 0.5 m or 45 degrees in a frame) while it is idle resets it to its guard there.
//!
//! The skeleton's modifier callback is set to physics: the simulated bodies move in physics frames.

use std::cell::Cell;
use std::time::Instant;

use glam::{Quat, Vec3};
use godot::builtin::{Basis, GString, PackedStringArray, PackedVector3Array, StringName, Transform3D, VarDictionary};
use godot::classes::skeleton_3d::ModifierCallbackModeProcess;
use godot::classes::{
    Engine, ISkeletonModifier3D, Node3D, PhysicalBone3D, PhysicalBoneSimulator3D, PhysicsBody3D, Skeleton3D,
    SkeletonModifier3D,
};
use godot::global::{godot_error, godot_warn};
use godot::meta::ToGodot;
use godot::obj::{Base, Gd, InstanceId, Singleton, WithBaseField};
use godot::prelude::{GodotClass, godot_api};
use punch_core::contract::character::Body;
use punch_core::rig::bone_map::{BoneMap, Role, map_bones_with};
use punch_core::rig::fist::FistPose;
use punch_core::rig::skeleton_pose::{
    Blend, BodyFrames, BodyRotations, SkeletonPoser, broken_rest, rig_arm_lengths, rig_fists, rig_shoulder_to_crown,
};
use punch_core::rig::transform::{SaidOnce, TransformError};

use crate::convert::{checked_quat, placement, quaternion, rigid, rotation, vec3, vector3};
use crate::punch_character::{PunchCharacter, is_teleport};
use crate::punch_controller::PunchController;
use crate::skin::skin_points;

thread_local! {
    /// Time all modifiers spent writing poses (µs) and the character-frames they wrote, for benchmarks.
    static COST: Cell<(f64, u64)> = const { Cell::new((0.0, 0)) };
}

/// The physical bones of a ragdoll.
fn physical_bones(simulator: &Gd<PhysicalBoneSimulator3D>) -> Vec<Gd<PhysicalBone3D>> {
    simulator.get_children().iter_shared().filter_map(|child| child.try_cast::<PhysicalBone3D>().ok()).collect()
}

/// Where the guard pose between punches comes from.
const GUARD_FROM_ANIMATION: i32 = 0;
const GUARD_FROM_CONTROLLER: i32 = 1;

/// Makes a game's own rigged character punch: add it as a child of the character's `Skeleton3D` (after any
/// modifier that must run first) and point `controller` at the `PunchController` that drives a
/// `PunchCharacter`. Every physics frame it writes the simulated upper body (spine to chest, clavicles, arms
/// and hands, the fingers closed into fists) onto the skeleton after the animation, blended with it around
/// punches, the head turned by the simulated head's snap when it is hit; the legs and everything else keep the
/// animation. Bones are found by name (`bone_map`, filled in automatically and
/// editable); a skeleton without the bones it needs gets one error, and then keeps its animation.
#[derive(GodotClass)]
#[class(base = SkeletonModifier3D, init, tool)]
pub struct PunchSkeletonModifier {
    /// The controller whose character's simulated body this skeleton shows.
    #[export_group(name = "Controller")]
    #[export]
    controller: Option<Gd<PunchController>>,
    /// Which bone plays each role (keys: hips, chest, neck, head, shoulder_l, upper_arm_l, forearm_l, hand_l
    /// and the same with _r; values: bone names). Empty or missing roles are found from the skeleton's bone
    /// names and parents; a name typed here holds its role. Filled in when the skeleton is read.
    #[export_group(name = "Mapping")]
    #[export]
    #[var(set = set_bone_map)]
    bone_map: VarDictionary,
    /// Seconds over which a punch's pose blends in from the animation's (eased in and out). The shipped punches
    /// land as soon as 0.06 s after they start: a longer blend-in shows the model's fist short of the simulated
    /// one when it lands.
    #[export_group(name = "Blending")]
    #[export(range = (0.0, 1.0, 0.01, or_greater, suffix = "s"))]
    #[init(val = 0.05)]
    blend_in_s: f32,
    /// Seconds over which the pose blends back to the animation's once the punch (and its recovery) is over.
    #[export(range = (0.0, 1.0, 0.01, or_greater, suffix = "s"))]
    #[init(val = 0.1)]
    blend_out_s: f32,
    /// Where the guard between punches comes from: the animation (the simulated body shows only while punching
    /// and recovering), or the controller (the simulated guard always shows).
    #[export(enum = (Animation = 0, Controller = 1))]
    #[init(val = GUARD_FROM_ANIMATION)]
    guard_source: i32,
    /// Close the hands into fists while the simulated body shows (by the same blend weight), so the skinned fist
    /// is where the simulated one lands: the finger bones below each mapped hand bend toward the palm (the thumb
    /// less), about axes read from the rig's rest (the finger's direction and the side its palm faces). Off: the
    /// fingers keep the animation's pose.
    #[export_group(name = "Hands")]
    #[export]
    #[init(val = true)]
    fist_curl: bool,
    /// Keep the simulated character on the rig (facing its front, shoulders on its shoulders) every physics frame,
    /// also while it punches, so the skeleton's fists go where the simulated ones go and a rig that walks or turns
    /// carries the simulated body along (its pelvis follows under physics). It is reset to its guard there when
    /// first placed, and when the rig jumps (more than 0.5 m or 45 degrees in a frame) between punches.
    #[export_group(name = "Simulated body")]
    #[export]
    #[init(val = true)]
    follow_rig: bool,
    /// Size the simulated arms to the rig's (upper arm, forearm to the fist centre: `rig_fist_centres()`, and
    /// shoulder width), so the skeleton's fists land where the simulated ones do: `PunchCharacter.size_arms`, once,
    /// before the first punch. A rig whose arm is outside 0.75 to 1.25 times the simulated one (shoulder to fist
    /// 0.619 m) gets one error and punches with the simulated body's own arms.
    #[export]
    #[init(val = true)]
    size_to_rig: bool,
    /// Also move the simulated head along its neck to the rig's head, with the arms (`size_to_rig` on):
    /// `PunchCharacter.size_head`, its crown as high above the shoulders as the top of the skin bound to the rig's
    /// head (else of a head-top bone; a rig with neither keeps the simulated head). A fist aimed at the `Head` then
    /// meets the model's face rather than its chin, and a block's gloves rise with it; but most rigs' heads sit
    /// 6-7 cm higher than the simulated body's, above the reach the shipped moves were trained for, so a punch
    /// aimed there says `target_out_of_reach` and reaches it less often (docs/hits.md). Off: the simulated head.
    #[export]
    size_head_to_rig: bool,
    /// Show the simulated body's capsules (for debugging); hidden otherwise. Physics is the same either way.
    #[export]
    #[var(set = set_show_simulated_body)]
    show_simulated_body: bool,

    /// The skeleton's bones as mapped, with the skeleton version it was read at.
    mapped: Option<Mapped>,
    /// Why the skeleton cannot be mapped (for the warnings); logged once per problem.
    problem: Option<String>,
    /// The poser for the character it was made for.
    poser: Option<(InstanceId, SkeletonPoser, [Gd<Node3D>; 6])>,
    /// The character whose arms were sized to this rig (tried once: a refusal is logged once).
    sized_for: Option<InstanceId>,
    /// The shoulder joints in the upper arms' frames ([right, left]), where the simulated shoulders are.
    shoulder_anchors: [Vec3; 2],
    blend: Blend,
    /// Names the pass calls every frame, made once (making one takes a lock).
    names: Names,
    /// The degenerate transforms (the skeleton's, a bone's) already reported: each cause is said once, not every
    /// frame it is skipped.
    said: SaidOnce,
    /// The character this modifier placed on the rig (and reset to its guard there) first.
    placed: Option<InstanceId>,
    /// The character read from the controller when its punch (or recovery) began: a punch keeps its character,
    /// so frames within one need not ask again (asking is a tenth of the pass).
    punching_character: Option<Gd<PunchCharacter>>,
    /// While its character is knocked down: the skeleton's ragdoll (`handed_off_to`) and whether its bones were given
    /// the simulated bodies' velocities yet, or `None` when the skeleton has none (looked for once a knock-down).
    handed_off: Option<Option<(Gd<PhysicalBoneSimulator3D>, bool)>>,
    base: Base<SkeletonModifier3D>,
}

struct Names {
    character: StringName,
    is_punching: StringName,
    is_recovering: StringName,
    is_knocked_down: StringName,
}

impl Default for Names {
    fn default() -> Self {
        Names {
            character: StringName::from("character"),
            is_punching: StringName::from("is_punching"),
            is_recovering: StringName::from("is_recovering"),
            is_knocked_down: StringName::from("is_knocked_down"),
        }
    }
}

/// What one pass poses from, read from the engine and checked: the simulated bodies' rotations in the skeleton's
/// space, the animation's local rotation of every written bone (`written_bones` order) and finger, the hips' global
/// rotation, and the global rotation of the spine's first bone's parent.
struct PoseInputs {
    rotations: BodyRotations,
    animated: Vec<Quat>,
    hips: Quat,
    fingers: Vec<Quat>,
    spine_parent: Basis,
}

struct Mapped {
    skeleton: InstanceId,
    version: u64,
    map: BoneMap,
    parents: Vec<i32>,
    rest: Vec<(Quat, Vec3)>,
    /// The finger bones' local rotations in a fist.
    fist: FistPose,
    /// The fist centres at rest, [right, left], skeleton space (`rig_fists`, with the hands' skin).
    fists: [Vec3; 2],
    /// How high the crown stands above the shoulders at rest, in the skeleton's units (`rig_shoulder_to_crown`, with
    /// the head's skin); `None` when the rig cannot say.
    shoulder_to_crown: Option<f32>,
}

#[godot_api]
impl ISkeletonModifier3D for PunchSkeletonModifier {
    fn ready(&mut self) {
        if let Some(mut skeleton) = self.base().get_skeleton()
            && !Engine::singleton().is_editor_hint()
        {
            skeleton.set_modifier_callback_mode_process(ModifierCallbackModeProcess::PHYSICS);
        }
        self.apply_visibility();
    }

    fn process_modification_with_delta(&mut self, delta: f64) {
        if Engine::singleton().is_editor_hint() {
            self.ensure_mapped();
            return;
        }
        let started = Instant::now();
        if self.modify(delta as f32) {
            let usec = started.elapsed().as_secs_f64() * 1e6;
            COST.with(|c| {
                let (total, frames) = c.get();
                c.set((total + usec, frames + 1));
            });
        }
    }

    fn skeleton_changed(&mut self, _old: Option<Gd<Skeleton3D>>, _new: Option<Gd<Skeleton3D>>) {
        self.mapped = None;
        self.poser = None;
        self.sized_for = None;
        self.problem = None;
        self.said.clear();
        self.ensure_mapped();
    }

    fn get_configuration_warnings(&self) -> PackedStringArray {
        self.configuration_warnings()
    }
}

#[godot_api]
impl PunchSkeletonModifier {
    /// Sets `bone_map` and maps the skeleton again with it (at once when in the tree).
    #[func]
    fn set_bone_map(&mut self, bone_map: VarDictionary) {
        self.bone_map = bone_map;
        self.mapped = None;
        self.poser = None;
        self.sized_for = None;
        self.problem = None;
        self.said.clear();
        if self.base().is_inside_tree() {
            self.ensure_mapped();
        }
    }

    /// Sets `show_simulated_body`: shows or hides the simulated body's capsules at once.
    #[func]
    fn set_show_simulated_body(&mut self, show: bool) {
        self.show_simulated_body = show;
        self.apply_visibility();
    }

    /// Reads the skeleton again and maps its bones (after renaming bones, editing `bone_map` or changing the skinned
    /// meshes that say where the fists are). Returns true when every required role has a bone.
    #[func]
    fn remap(&mut self) -> bool {
        self.mapped = None;
        self.poser = None;
        self.sized_for = None;
        self.problem = None;
        self.said.clear();
        self.ensure_mapped()
    }

    /// True when the skeleton's bones are mapped (every required role has a bone).
    #[func]
    fn is_mapped(&self) -> bool {
        self.mapped.is_some()
    }

    /// The rig's fist centres at rest, [right, left], in the skeleton's space: three quarters of the way from
    /// each hand bone's head to its knuckles, moved across the hand onto the middle of the hand's skin when a
    /// skinned mesh deforms the skeleton. The modifier puts these points on the simulated fists' centres and sizes
    /// the forearms to reach them. Read when the skeleton is mapped: call `remap()` after changing its meshes.
    /// Empty while the skeleton is not mapped.
    #[func]
    fn rig_fist_centres(&self) -> PackedVector3Array {
        self.mapped.as_ref().map_or_else(PackedVector3Array::new, |m| m.fists.iter().map(|&f| vector3(f)).collect())
    }

    /// What the editor's warning icon says: no skeleton or controller, the roles with no bone (and why).
    #[func]
    fn configuration_warnings(&self) -> PackedStringArray {
        let mut warnings = PackedStringArray::new();
        if self.base().get_skeleton().is_none() {
            warnings.push("PunchSkeletonModifier must be a child of a Skeleton3D.");
        }
        if self.controller.is_none() {
            warnings.push("Set `controller` to the PunchController that drives a PunchCharacter.");
        }
        if let Some(problem) = &self.problem {
            warnings.push(problem.as_str());
        }
        if let Some(mapped) = &self.mapped {
            let unmapped: Vec<String> = mapped.map.unmapped().iter().map(|r| format!("{r} ({})", r.key())).collect();
            if !unmapped.is_empty() {
                warnings.push(&format!(
                    "No bone found for: {} (optional; those bones keep the animation).",
                    unmapped.join(", ")
                ));
            }
        }
        warnings
    }

    /// The blend weight now: 0 shows the animation, 1 the simulated body.
    #[func]
    fn blend_weight(&self) -> f32 {
        self.blend.weight()
    }

    /// Why the skeleton could not be mapped ("" when it is).
    #[func]
    fn mapping_problem(&self) -> GString {
        GString::from(self.problem.as_deref().unwrap_or_default())
    }

    /// The `PhysicalBoneSimulator3D` the skeleton is handed to while its character is knocked down (null when it is
    /// not, or when the skeleton has no simulator with physical bones: then it shows the simulated body hanging limp).
    /// From the first pass after `knocked_down` until `recover()` or the next punch.
    #[func]
    fn handed_off_to(&self) -> Option<Gd<PhysicalBoneSimulator3D>> {
        self.handed_off.clone().flatten().map(|(simulator, _)| simulator).filter(|s| s.is_instance_valid())
    }
}

impl PunchSkeletonModifier {
    /// The bones this modifier writes each frame, in order (read by tests through `PunchProbe`).
    #[cfg(feature = "probe")]
    pub fn written_bones(&self) -> PackedStringArray {
        let mut names = PackedStringArray::new();
        if let (Some((_, poser, _)), Some(skeleton)) = (&self.poser, self.base().get_skeleton()) {
            for bone in poser.written_bones() {
                names.push(&skeleton.get_bone_name(bone as i32));
            }
            for (bone, _) in self.fist_bones() {
                names.push(&skeleton.get_bone_name(bone as i32));
            }
        }
        names
    }

    /// Mean time (µs) all modifiers spent per character-frame writing poses since the last call, and how many
    /// character-frames that was (read by benchmarks through `PunchProbe`).
    #[cfg(feature = "probe")]
    pub fn take_cost_usec() -> VarDictionary {
        let (usec, frames) = COST.with(|c| c.replace((0.0, 0)));
        let mut cost = VarDictionary::new();
        cost.set("usec_per_frame", if frames == 0 { 0.0 } else { usec / frames as f64 });
        cost.set("frames", frames as i64);
        cost
    }

    /// The finger bones curled into fists (none when `fist_curl` is off).
    fn fist_bones(&self) -> impl Iterator<Item = (usize, Quat)> + '_ {
        self.mapped.as_ref().filter(|_| self.fist_curl).into_iter().flat_map(|m| m.fist.bones())
    }

    fn name(&self) -> String {
        self.base().get_name().to_string()
    }

    /// Maps the skeleton if it is not (or it changed). Logs one error per problem. True when mapped.
    fn ensure_mapped(&mut self) -> bool {
        let Some(skeleton) = self.base().get_skeleton() else {
            return false;
        };
        if let Some(mapped) = &self.mapped
            && mapped.skeleton == skeleton.instance_id()
            && mapped.version == skeleton.get_version()
        {
            return true;
        }
        if self.problem.is_some() {
            return false;
        }
        self.poser = None;
        self.sized_for = None;
        match self.read_skeleton(&skeleton) {
            Ok(mapped) => {
                let mut filled = VarDictionary::new();
                for role in Role::ALL {
                    let name = mapped.map.bone(role).map(|b| skeleton.get_bone_name(b as i32)).unwrap_or_default();
                    filled.set(role.key(), &name);
                }
                if filled != self.bone_map {
                    self.bone_map = filled;
                    self.base_mut().notify_property_list_changed();
                }
                self.mapped = Some(mapped);
            }
            Err(problem) => {
                godot_error!("PunchSkeletonModifier '{}': {problem}. The skeleton keeps its animation.", self.name());
                self.problem = Some(problem);
                self.mapped = None;
            }
        }
        self.base_mut().update_configuration_warnings();
        self.mapped.is_some()
    }

    fn read_skeleton(&self, skeleton: &Gd<Skeleton3D>) -> Result<Mapped, String> {
        let count = skeleton.get_bone_count();
        let names: Vec<String> = (0..count).map(|b| skeleton.get_bone_name(b).to_string()).collect();
        let parents: Vec<i32> = (0..count).map(|b| skeleton.get_bone_parent(b)).collect();
        let chosen_names: Vec<(Role, String)> = Role::ALL
            .into_iter()
            .filter_map(|role| {
                let name = self.bone_map.get(role.key()).map(|v| v.to_string()).unwrap_or_default();
                (!name.is_empty()).then_some((role, name))
            })
            .collect();
        let chosen: Vec<(Role, &str)> = chosen_names.iter().map(|(r, n)| (*r, n.as_str())).collect();
        let map = map_bones_with(&names, &parents, &chosen)
            .map_err(|e| format!("{e}; set the missing roles in `bone_map`"))?;
        // A broken import (a NaN, a bone scaled to 0 in its rest) is named with its bone when the pose reads that
        // bone; elsewhere (a leg, an accessory) it does not matter and reads as no rotation.
        let mut broken = vec![None; count.max(0) as usize];
        let rest: Vec<(Quat, Vec3)> = (0..count)
            .map(|b| match placement(skeleton.get_bone_global_rest(b)) {
                Ok(rest) => rest,
                Err(cause) => {
                    broken[b as usize] = Some(cause);
                    (Quat::IDENTITY, Vec3::ZERO)
                }
            })
            .collect();
        if let Some((bone, cause)) = broken_rest(&map, &parents, &broken) {
            return Err(format!(
                "bone '{}''s rest {cause}: the skeleton's import is broken (import it again, or fix that bone's rest)",
                names[bone]
            ));
        }
        let fist = FistPose::new(&map, &names, &parents, &rest);
        let [right_hand, left_hand, head] = skin_points(skeleton, [map.right.hand, map.left.hand, map.head], &parents);
        let fists = rig_fists(&map, &parents, &rest, [&right_hand, &left_hand]);
        let shoulder_to_crown = rig_shoulder_to_crown(&map, &parents, &rest, &head, 1.0);
        Ok(Mapped {
            skeleton: skeleton.instance_id(),
            version: skeleton.get_version(),
            map,
            parents,
            rest,
            fist,
            fists,
            shoulder_to_crown,
        })
    }

    /// The character the controller drives, if both are alive.
    fn character(&self) -> Option<Gd<PunchCharacter>> {
        let controller = self.controller.as_ref().filter(|c| c.is_instance_valid())?;
        controller.get(&self.names.character).try_to::<Option<Gd<PunchCharacter>>>().ok().flatten()
    }

    fn apply_visibility(&mut self) {
        if Engine::singleton().is_editor_hint() {
            return;
        }
        if let Some(mut character) = self.character() {
            character.set_visible(self.show_simulated_body);
        }
    }

    /// Makes the poser for `character` (its rest geometry must be read: the character is ready), first sizing
    /// its arms to the rig's when `size_to_rig` is on (which resets its pose: never while it punches; a poser
    /// made during a punch is made again, sized, at the first frame the character is idle).
    fn ensure_poser(&mut self, character: &Gd<PunchCharacter>, busy: bool) -> Result<(), String> {
        let id = character.instance_id();
        let needs_sizing = self.size_to_rig && self.sized_for != Some(id);
        if self.poser.as_ref().is_some_and(|(poser_for, ..)| *poser_for == id) && (busy || !needs_sizing) {
            return Ok(());
        }
        let mapped = self.mapped.as_ref().ok_or("the skeleton is not mapped")?;
        if needs_sizing && !busy {
            self.sized_for = Some(id);
            let scale = self.base().get_skeleton().map_or(1.0, |s| s.get_global_transform().basis.get_scale().y);
            let lengths = rig_arm_lengths(&mapped.map, &mapped.rest, mapped.fists, scale);
            // Called, not bound; on failure the character says why (one error) and keeps its arms.
            character.clone().call(
                "size_arms",
                &[
                    lengths.upper_arm_m.to_variant(),
                    lengths.forearm_m.to_variant(),
                    lengths.shoulder_width_m.to_variant(),
                ],
            );
            if let Some(crown) = mapped.shoulder_to_crown.filter(|_| self.size_head_to_rig) {
                character.clone().call("size_head", &[(crown * scale).to_variant()]);
            }
        }
        let (geometry, bodies) = {
            let bound = character.bind();
            let rig = bound.rig().ok_or("the PunchCharacter is not ready")?;
            let root = bound.standing().ok_or("the PunchCharacter is not ready")?;
            let bodies: [Gd<Node3D>; 6] =
                [Body::Torso, Body::UpperArmR, Body::ForearmR, Body::UpperArmL, Body::ForearmL, Body::Head]
                    .map(|b| rig.bodies[b.index()].clone().upcast::<Node3D>());
            (rig.geometry_at(root), bodies)
        };
        let shoulder = |name: &str| -> Result<Vec3, String> {
            character
                .get_node_or_null(name)
                .and_then(|n| n.try_cast::<Node3D>().ok())
                .map(|n| vec3(n.get_position()))
                .ok_or_else(|| format!("the PunchCharacter has no joint '{name}'"))
        };
        self.shoulder_anchors = [geometry.joint_anchors[1].1, geometry.joint_anchors[3].1];
        let frames = BodyFrames::from_geometry(&geometry)
            .map_err(|e| e.to_string())?
            .with_shoulders([shoulder("ShoulderR")?, shoulder("ShoulderL")?]);
        let poser = SkeletonPoser::new(&mapped.map, &mapped.parents, &mapped.rest, mapped.fists, frames)
            .map_err(|e| e.to_string())?;
        self.poser = Some((character.instance_id(), poser, bodies));
        let bones = Body::ALL.map(|body| {
            mapped.map.bone_showing(body).map_or_else(StringName::default, |bone| {
                self.base()
                    .get_skeleton()
                    .map_or_else(StringName::default, |s| StringName::from(&s.get_bone_name(bone as i32)))
            })
        });
        character.clone().bind_mut().set_rig_bones(bones);
        Ok(())
    }

    /// One modification pass. Returns true when it wrote poses.
    fn modify(&mut self, delta_s: f32) -> bool {
        if !self.ensure_mapped() {
            return false;
        }
        let Some(skeleton) = self.base().get_skeleton() else { return false };
        // A skeleton (or a model above it) scaled to 0, mirrored or NaN has no frame to pose in: the frame is skipped
        // and the skeleton keeps its animation until it has one (said once per cause). Checked before the arms are
        // sized to the rig, so a model that pops in from scale 0 is sized once it has its size.
        let skeleton_global = skeleton.get_global_transform();
        let skeleton_rotation = match rigid(skeleton_global).and_then(|_| rotation(skeleton_global.basis)) {
            Ok(rotation) => rotation,
            Err(cause) => {
                self.skip(&format!("the skeleton '{}'", skeleton.get_name()), cause);
                return false;
            }
        };
        let Some(controller) = self.controller.clone().filter(|c| c.is_instance_valid()) else {
            self.blend.set(false);
            return false;
        };
        // Called, not bound: a pass may run while the controller is bound (a signal handler moving a node).
        let mut controller = controller.upcast::<godot::classes::Object>();
        let punching = controller.call(&self.names.is_punching, &[]).try_to::<bool>().unwrap_or(false);
        let knocked_down = controller.call(&self.names.is_knocked_down, &[]).try_to::<bool>().unwrap_or(false);
        let busy = punching
            || knocked_down
            || controller.call(&self.names.is_recovering, &[]).try_to::<bool>().unwrap_or(false);
        let cached = self.punching_character.clone().filter(|c| busy && c.is_instance_valid());
        let Some(character) = cached.or_else(|| self.character()) else {
            self.blend.set(false);
            return false;
        };
        self.punching_character = Some(character.clone());
        if character.bind().rig().is_none() {
            return false;
        }
        if let Err(problem) = self.ensure_poser(&character, busy) {
            if self.problem.is_none() {
                godot_error!("PunchSkeletonModifier '{}': {problem}. The skeleton keeps its animation.", self.name());
                self.problem = Some(problem);
                self.base_mut().update_configuration_warnings();
            }
            return false;
        }
        if self.hand_off(&skeleton, &character, knocked_down) {
            return false;
        }
        let active = busy || self.guard_source == GUARD_FROM_CONTROLLER;
        if self.follow_rig {
            self.place_character(character, skeleton_global, skeleton_rotation, busy);
        }
        // Everything the pose is made from, read and checked before a bone is written: a bone that an animation
        // scaled to 0 or gave a NaN skips the frame (said once), and the skeleton keeps its animation.
        let inputs = match self.read_pose_inputs(&skeleton, skeleton_rotation) {
            Ok(inputs) => inputs,
            Err((subject, cause)) => {
                self.skip(&subject, cause);
                return false;
            }
        };
        let weight = self.blend.advance(active, delta_s, self.blend_in_s, self.blend_out_s);
        if weight <= 0.0 {
            return false;
        }
        let Some((_, poser, bodies)) = &self.poser else { return false };
        let PoseInputs { rotations, animated, hips, fingers, spine_parent } = inputs;
        let written: Vec<usize> = poser.written_bones().collect();
        let blending = weight < 1.0;
        let lookup = |bone: usize| written.iter().position(|&b| b == bone).map_or(Quat::IDENTITY, |i| animated[i]);
        let targets = poser.pose(&rotations, hips, lookup);
        let mut skeleton = skeleton;
        for ((&bone, anim), target) in written.iter().zip(&animated).zip(&targets) {
            let q = if blending { anim.slerp(*target, weight).normalize() } else { *target };
            skeleton.set_bone_pose_rotation(bone as i32, quaternion(q));
        }
        for ((bone, fist), anim) in self.fist_bones().zip(&fingers) {
            let q = if blending { anim.slerp(fist, weight).normalize() } else { fist };
            skeleton.set_bone_pose_rotation(bone as i32, quaternion(q));
        }
        // The spine bends about other points than the simulated waist: the spine's first bone is shifted so that
        // the rig's shoulders sit where the simulated ones are (by the blend weight's share).
        let inverse = skeleton_global.affine_inverse();
        let simulated_mid = (0..2).fold(Vec3::ZERO, |sum, side| {
            let body = bodies[1 + 2 * side].get_global_transform();
            sum + 0.5 * vec3(inverse * (body * vector3(self.shoulder_anchors[side])))
        });
        let (right, left) = poser.upper_arms();
        let rig_mid = 0.5
            * (vec3(skeleton.get_bone_global_pose(right as i32).origin)
                + vec3(skeleton.get_bone_global_pose(left as i32).origin));
        let first = poser.spine_root() as i32;
        let shift = spine_parent.inverse() * vector3(weight * (simulated_mid - rig_mid));
        let position = skeleton.get_bone_pose_position(first) + shift;
        // A bone's position that is not a number (an animation's) is left as the animation has it.
        if vec3(position).is_finite() {
            skeleton.set_bone_pose_position(first, position);
        }
        true
    }

    /// The knock-down hand-off: while the character is knocked down, a `PhysicalBoneSimulator3D` child of the skeleton
    /// (the game's ragdoll, if it set one up) simulates the skeleton, each physical bone started with the velocity of
    /// the simulated body it moves with (`BoneMap::body_of`) and no collision with the simulated bodies it stands in,
    /// and this modifier writes nothing; when the character is brought back (`recover()`, a punch) the simulation
    /// stops and the modifier poses the skeleton again. Returns whether the skeleton is the ragdoll's this pass.
    /// Without a simulator the skeleton shows the simulated body hanging limp in its joints.
    fn hand_off(&mut self, skeleton: &Gd<Skeleton3D>, character: &Gd<PunchCharacter>, knocked_down: bool) -> bool {
        if !knocked_down {
            if let Some(Some((mut simulator, _))) = self.handed_off.take()
                && simulator.is_instance_valid()
            {
                simulator.physical_bones_stop_simulation();
            }
            return false;
        }
        match &mut self.handed_off {
            Some(None) => return false,
            Some(Some((simulator, moving))) if simulator.is_instance_valid() => {
                // The bones turn dynamic with the step after the simulation starts: a velocity given before is lost.
                if !*moving {
                    *moving = true;
                    Self::start_moving(simulator, character, self.mapped.as_ref());
                }
                return true;
            }
            _ => {}
        }
        let ragdoll = skeleton
            .get_children()
            .iter_shared()
            .find_map(|child| child.try_cast::<PhysicalBoneSimulator3D>().ok())
            .map(|simulator| (physical_bones(&simulator), simulator))
            .filter(|(bones, _)| !bones.is_empty());
        let Some((bones, mut simulator)) = ragdoll else {
            self.handed_off = Some(None);
            return false;
        };
        let bodies: Vec<Gd<PhysicsBody3D>> = character.bind().rig().map_or_else(Vec::new, |rig| rig.bodies.clone());
        for mut bone in bones {
            // The ragdoll stands where the simulated body does: they would push each other apart.
            for body in &bodies {
                bone.add_collision_exception_with(body);
            }
        }
        simulator.set_active(true);
        simulator.physical_bones_start_simulation();
        self.handed_off = Some(Some((simulator, false)));
        true
    }

    /// Gives each physical bone the velocity of the simulated body it moves with.
    fn start_moving(simulator: &Gd<PhysicalBoneSimulator3D>, character: &Gd<PunchCharacter>, mapped: Option<&Mapped>) {
        let states = character.bind().rig().map(|rig| rig.read_bodies());
        let (Some(mapped), Some(Ok(states))) = (mapped, states) else { return };
        for mut bone in physical_bones(simulator) {
            let Ok(index) = usize::try_from(bone.get_bone_id()) else { continue };
            let state = &states[mapped.map.body_of(index, &mapped.parents).index()];
            bone.set_linear_velocity(vector3(state.linear_velocity));
            bone.set_angular_velocity(vector3(state.angular_velocity));
        }
    }

    /// Reads what a pass poses from, checked (see `PoseInputs`); an error names what is degenerate and why.
    fn read_pose_inputs(
        &self,
        skeleton: &Gd<Skeleton3D>,
        skeleton_rotation: Quat,
    ) -> Result<PoseInputs, (String, TransformError)> {
        let Some((_, poser, bodies)) = &self.poser else {
            return Err(("the poser".into(), TransformError::NotFinite));
        };
        let bone = |b: usize| format!("bone '{}'", skeleton.get_bone_name(b as i32));
        let local = |b: usize| checked_quat(skeleton.get_bone_pose_rotation(b as i32)).map_err(|c| (bone(b), c));
        let global = |b: usize| rotation(skeleton.get_bone_global_pose(b as i32).basis).map_err(|c| (bone(b), c));
        let to_skeleton = skeleton_rotation.inverse();
        let body = |i: usize| {
            rotation(bodies[i].get_global_transform().basis)
                .map(|q| to_skeleton * q)
                .map_err(|c| (format!("the simulated body '{}'", bodies[i].get_name()), c))
        };
        let rotations = BodyRotations {
            torso: body(0)?,
            head: body(5)?,
            upper_arm: [body(1)?, body(3)?],
            forearm: [body(2)?, body(4)?],
        };
        // The animation's pose: every written bone's (read for the blend, and for the spine always).
        let animated = poser.written_bones().map(local).collect::<Result<Vec<_>, _>>()?;
        let fingers = self.fist_bones().map(|(b, _)| local(b)).collect::<Result<Vec<_>, _>>()?;
        let hips = global(poser.hips())?;
        let parent = usize::try_from(skeleton.get_bone_parent(poser.spine_root() as i32)).unwrap_or(poser.hips());
        global(parent)?; // checked: its basis has an inverse
        let spine_parent = skeleton.get_bone_global_pose(parent as i32).basis;
        Ok(PoseInputs { rotations, animated, hips, fingers, spine_parent })
    }

    /// Skips this frame: says why, once per cause and subject. A mirrored skeleton is an error (the model must
    /// change); scale 0 or a NaN a warning (a game may do it for a while: a model popping in, hidden, animated).
    fn skip(&mut self, subject: &str, cause: TransformError) {
        if !self.said.first(subject, cause) {
            return;
        }
        let name = self.name();
        if cause == TransformError::Mirrored {
            godot_error!(
                "PunchSkeletonModifier '{name}': {subject} is mirrored (a negative scale on it or a parent): the \
                 simulated body cannot be shown on a mirrored model, so the skeleton keeps its animation; use the \
                 other stance (the other hand) instead of a mirrored model, and turn the model with a rotation"
            );
        } else {
            godot_warn!(
                "PunchSkeletonModifier '{name}': {subject} {cause}: the skeleton keeps its animation until it has a \
                 usable transform again (said once)"
            );
        }
    }

    /// Keeps the simulated character's root on the rig (see `follow_rig`); a teleport-sized jump while it is
    /// neither punching nor recovering (`busy`) also resets it to its guard there.
    fn place_character(
        &mut self,
        mut character: Gd<PunchCharacter>,
        skeleton: Transform3D,
        skeleton_rotation: Quat,
        busy: bool,
    ) {
        let Some((_, poser, _)) = &self.poser else { return };
        let now = character.get_global_transform();
        // A character (or its parent) at scale 0 or NaN cannot be placed: setting its global transform would invert
        // its parent's. It says so itself (`PunchCharacter`), once.
        let Ok(now_rotation) = rotation(now.basis).and_then(|q| rigid(now).map(|_| q)) else { return };
        let scale = skeleton.basis.get_scale();
        let (rotation, origin) = poser.character_placement(skeleton_rotation, vec3(skeleton.origin), scale.y);
        let moved = (vec3(now.origin) - origin).length() > 1e-4 || now_rotation.angle_between(rotation) > 1e-3;
        let basis = Basis::from_quaternion(quaternion(rotation));
        let placement = Transform3D::new(basis, vector3(origin));
        if moved {
            character.set_global_transform(placement);
        }
        let first = self.placed != Some(character.instance_id());
        if !busy && (first || is_teleport(now, placement)) {
            self.placed = Some(character.instance_id());
            character.call("reset_pose", &[]);
        }
    }
}
