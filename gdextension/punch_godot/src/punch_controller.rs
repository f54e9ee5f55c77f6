//! `PunchController`: plays a trained punching policy on a `PunchCharacter` in a game. What a punch is and
//! how it goes (phases, decisions, noise, hits, events) is `punch_core::game::lifecycle`; this class reads the
//! engine into it, drives the joints with what comes back, and turns its events into signals.
//!
//! Signals are emitted with no borrow of the controller held (`#[func(gd_self)]`, and the frame pass), so a
//! handler may do anything: free this or another controller, its character or its target, punch again.

// The `hit` signal's generated emitter takes its eight arguments one by one, as a handler receives them.
#![allow(clippy::too_many_arguments)]

use std::rc::Rc;
use std::time::Instant;

use glam::Vec3;
use godot::builtin::{GString, PackedStringArray, StringName, VarArray, VarDictionary, Vector2, Vector3};
use godot::classes::notify::NodeNotification;
use godot::classes::{Engine, INode, Node, Node3D, PhysicsShapeQueryParameters3D, SceneTree, SphereShape3D};
use godot::global::{godot_error, godot_warn};
use godot::obj::{Base, Gd, InstanceId, NewGd, Singleton, WithBaseField, WithSignals, WithUserSignals};
use godot::prelude::PhantomVar;
use godot::prelude::{Export, GodotClass, GodotConvert, ToGodot, Var, godot_api, try_load};
use punch_core::contract::character::{Body, DEFAULT_DECISION_PERIOD, DOF_COUNT};
use punch_core::contract::mirror::mirror_point;
use punch_core::contract::sensing::{CharacterGeometry, FrameReading};
use punch_core::contract::spec::{ReachVolume, hand_far_m};
use punch_core::contract::stance::{high_guard_rad, turned_toward};
use punch_core::game::lifecycle::{Drive, Ending, Event, FrameNeeds, Lifecycle, NoiseSettings, PunchStart};
use punch_core::game::moves::{Hand, Move, Side, Stance};
use punch_core::game::policy_gate::{DecisionRequest, PunchingPolicy, decide_batched};
use punch_core::game::punch::{Punch, PunchSummary, Recovery};
use punch_core::rig::transform::TransformError;

use crate::convert::{rigid, vec3, vector3};
use crate::engine_io::{add_area_touches, add_bag_contacts, read_forearm_contacts};
use crate::punch_character::PunchCharacter;
use crate::punch_controller_registry::PunchControllerRegistry;
use crate::punch_moveset::PunchMoveset;
use crate::punch_policy::PunchPolicy;
use crate::target::Target;

/// The addon's moveset, which `punch(move)` plays when `moveset` is empty (the square guard's).
const ADDON_MOVESET: &str = "res://addons/punch_controller/policies/boxing.tres";
/// The addon's moveset for a character in its stance's guard, which `punch(move)` plays when `moveset` is empty and
/// `stance_pose` is on.
const ADDON_STANCE_MOVESET: &str = "res://addons/punch_controller/policies/boxing_stance.tres";

/// Which hand leads (`PunchController.stance`).
#[derive(GodotConvert, Var, Export, Default, Debug, Clone, Copy, PartialEq, Eq)]
#[godot(via = i64)]
pub enum PunchStance {
    /// The left hand leads.
    #[default]
    Orthodox,
    /// The right hand leads.
    Southpaw,
}

impl From<PunchStance> for Stance {
    fn from(stance: PunchStance) -> Self {
        match stance {
            PunchStance::Orthodox => Stance::Orthodox,
            PunchStance::Southpaw => Stance::Southpaw,
        }
    }
}

/// What `punch()` was asked to throw: a policy, the hand it punches with, and the move it is.
struct Throw {
    policy: Rc<PunchingPolicy>,
    hand: Hand,
    punch_move: Option<Move>,
    /// From the fist's first contact (or the punch's last frame) to the cancel window, s (`PunchMoveset`).
    cancel_delay_s: f32,
    /// How near the guard it starts with `guard_first`, rad (`PunchMoveset`).
    guard_tolerance_rad: f32,
}

/// A move that can be thrown now (`checked`): what throws it, at which character (its geometry where it stands) and
/// target (where it is, global).
struct Checked {
    throw: Throw,
    character: Gd<PunchCharacter>,
    target: Target,
    geometry: CharacterGeometry,
    target_position: Vec3,
}

/// A punch ready to start: its start, its policy's identity (for the noise), and the character it drives.
struct Prepared {
    start: PunchStart<Rc<PunchingPolicy>>,
    identity: usize,
    character: Gd<PunchCharacter>,
}

/// How a controller reacted to its character being struck.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Reaction {
    /// Back to guard (and a punch ended, unless hyper-armour kept it).
    Flinched,
    /// As `Flinched`, from a hit of at least `stagger_impulse_ns`.
    Staggered,
    /// Limp, the punch ended: at least `knockdown_impulse_ns`.
    KnockedDown,
}

/// The signals of this class, as the frame pass and the class's own functions emit them.
type Signals<'c> = <PunchController as WithSignals>::SignalCollection<'c, PunchController>;

/// Makes a `PunchCharacter` punch a target with a trained policy (an .onnx file made by `punch train`).
/// Each punch differs when `noise_sigma` > 0: Gaussian noise of that standard deviation is added to the
/// policy's mean action at every decision (or at the first `noise_decisions` only). All controllers that
/// play the same `PunchPolicy` resource share one model and run in one inference call per decision tick.
///
/// A punch asked for away from the guard pose first returns the character to guard (`guard_first`); after
/// it, the character returns to its guard pose under physics (`auto_recover`). Every `punch_started` is
/// followed by exactly one `punch_finished`, whatever happens meanwhile (the controller, its character or its
/// target freed, another punch asked for). Drive each character with one controller at a time: a controller
/// that starts driving a character another one drives takes it over (the other's punch ends, interrupted,
/// with a warning). Two punches are identical (sigma 0, or the same seed) when they start from the same
/// state of the world: the character at rest in its guard pose (as after `recover()` from rest, or in a
/// scene that has just started) and the target at rest at the same place relative to it.
#[derive(GodotClass)]
#[class(base = Node, init)]
pub struct PunchController {
    /// The policy: an .onnx file from `punch train` (a `PunchPolicy` resource: pick the file, or
    /// `load("res://....onnx")`). The addon ships one per style in `addons/punch_controller/policies/`.
    /// A new policy plays from the next punch; a punch running when it is set plays on with the one it
    /// started with. Setting the policy it already has changes nothing.
    #[export_group(name = "Policy")]
    #[export]
    #[var(set = set_policy)]
    policy: Option<Gd<PunchPolicy>>,
    /// Standard deviation of the noise added to the policy's mean action, in action units (actions lie in
    /// [-1, 1]). Values outside 0..1 are clamped, and values that are not numbers refused, with a warning.
    /// Takes effect at the next decision. A policy trained with a motion style spreads it over its joints
    /// (its `punch_noise_scale` metadata): the guard arm and the trunk's lean get a twentieth and a tenth of
    /// it, so the punch varies and the guard holds.
    #[export(range = (0.0, 1.0, 0.01))]
    #[var(set = set_noise_sigma)]
    noise_sigma: f32,
    /// Noise on the first k decisions of a punch only; -1 puts noise on every decision.
    #[export(range = (-1.0, 20.0, 1.0, or_greater))]
    #[init(val = -1)]
    noise_decisions: i32,
    /// Seed of the noise: the same seed and sigma give the same sequence of punches. A new seed takes
    /// effect at the next punch.
    #[export]
    seed: i64,
    /// Physics frames each decision is held for: the policy's own (its `punch_decision_period`; 5 for the addon's
    /// policies, and when no policy is set). Read-only: a policy plays only at the period it was trained with
    /// (the period is part of its spec hash), so it is not a setting; it was once an inspector field, and any other
    /// value made `punch()` refuse the policy.
    #[var(get = get_decision_period, no_set)]
    decision_period: PhantomVar<i32>,

    /// The policies of the six moves `punch(move)` throws by name (`PunchMoveset`); empty: the addon's,
    /// `res://addons/punch_controller/policies/boxing.tres`, or with `stance_pose` on `boxing_stance.tres` (its
    /// moves trained from the stance's guard). A new moveset plays from the next punch.
    #[export_group(name = "Moves")]
    #[export]
    moveset: Option<Gd<PunchMoveset>>,
    /// Which hand leads: ORTHODOX (the left, the default) or SOUTHPAW (the right). The jab, the lead hook and the
    /// lead uppercut are the lead hand's, the other three the rear's; a left-hand punch plays its policy
    /// mirrored. With `stance_pose` on, an idle character turns into the new stance's guard at once; a punch
    /// plays on as it started.
    #[export]
    #[var(set = set_stance)]
    stance: PunchStance,
    /// Stand in the stance's guard: the trunk turned 30° to bring the lead shoulder forward, the lead hand a little
    /// ahead (docs/moves.md). Recoveries drive there, and a punch asked for away from it returns there first
    /// (`guard_first`). Off (the default): the square guard `boxing.tres`'s policies were trained from. On, an empty
    /// `moveset` plays `res://addons/punch_controller/policies/boxing_stance.tres`, whose lead moves and rear
    /// uppercut were trained from the stance's guard (BENCHMARKS.md, "The six moves"); a moveset of the game's own
    /// plays as set. The character stands in the guard from the moment the controller is ready: set while it is
    /// idle, it turns into the guard at once (quietly: no `recovered`); set during a punch or recovery, from the
    /// next one.
    #[export]
    #[var(set = set_stance_pose)]
    stance_pose: bool,
    /// The move `punch()` throws when it is given none ("jab", "cross", "lead_hook", "rear_hook",
    /// "lead_uppercut", "rear_uppercut"); empty (the default): `policy`, with the right hand, as trained.
    #[export]
    default_move: StringName,

    /// The character to drive. A new character is driven from the next punch.
    #[export_group(name = "Character and target")]
    #[export]
    character: Option<Gd<PunchCharacter>>,
    /// What to punch: any Node3D (a sandbag, a RigidBody3D, CharacterBody3D, StaticBody3D or Area3D, a
    /// marker or bone attachment on another character). The policy aims at its position; its physics object
    /// (the node itself, else a child, else the nearest ancestor that is one) is what the policy feels.
    #[export]
    target: Option<Gd<Node3D>>,
    /// The physics layers whose bodies count as hit when a fist touches them (the target always counts).
    /// Only what the character's bodies collide with can be touched (their collision masks: layers 1 to 3 in
    /// the addon's character scene).
    #[export(flags_3d_physics)]
    #[init(val = u32::MAX)]
    hit_layers: u32,
    /// Also count Area3D overlaps of a fist (hurtboxes on `hit_layers`) as hits, with no impulse. An Area3D
    /// target is always checked. Costs a shape query per fist and frame while punching.
    #[export]
    hit_areas: bool,

    /// A punch asked for while the character is away from its guard pose (the end of an earlier punch,
    /// mid-recovery, the next punch of a combo) first returns it to guard under physics until every joint is within
    /// the move's tolerance of its guard angle (the moveset's "Returns to guard": 6° and slower than 1 rad/s, the
    /// uppercuts settled; at most 0.5 s; a punch with no move: 6°), then plays the policy: punches land far more
    /// often from there (BENCHMARKS.md, "after an earlier punch"). Off: the policy starts from
    /// whatever pose the arms are in. A punch from the guard starts at once either way, but for a policy trained
    /// from a load (its file's `punch_start_load`: the lead hook's elbow raised out, the lead uppercut's fist dropped;
    /// docs/moves.md): its arm is always drawn into the load first, the same way.
    #[export_group(name = "Behaviour")]
    #[export]
    #[init(val = true)]
    guard_first: bool,
    /// After a punch, drive the character back to its guard pose under physics (`recovered` says when it
    /// is there). Off: the joints hold where the punch left them.
    #[export]
    #[init(val = true)]
    auto_recover: bool,
    /// Punch as soon as the scene starts.
    #[export]
    autostart: bool,
    /// When its character is struck (another controller's fist, or the game's `PunchCharacter.take_hit`), the
    /// punch that runs gives way (`punch_finished` says `"struck"`; what was queued is dropped) and the body,
    /// pushed by the hit, is driven back to its guard (`recovered` when there). Off: the hit only pushes the
    /// bodies, and the joints hold where it left them until `recover()` or the next punch.
    #[export_group(name = "Taking hits")]
    #[export]
    #[init(val = true)]
    react_to_hits: bool,
    /// A punch that runs is not ended by a hit (the body is still pushed; the punch plays on, from wherever the
    /// hit left the arms). Fighting games call it hyper-armour. A hit between punches still sends the body back
    /// to guard, and a knock-down ends the punch all the same.
    #[export]
    hyper_armour: bool,
    /// A hit at least this hard (N s) emits `staggered` as the body is driven back to guard. The addon's punches
    /// strike a sandbag with 5-10 N s; a real Olympic straight carries about 27.
    #[export(range = (0.0, 1000.0, 1.0, or_greater))]
    #[init(val = 60.0)]
    stagger_impulse_ns: f32,
    /// A hit at least this hard (N s) knocks the character down: the punch ends, the joint motors go off (the body
    /// hangs in its joints' limits over the game's pelvis) and `knocked_down` is emitted; it stays down until
    /// `recover()` or the next punch. 320 N s is 4 times an 80 kg body's mass, as godot-active-ragdoll knocks down.
    #[export(range = (0.0, 1000.0, 1.0, or_greater))]
    #[init(val = 320.0)]
    knockdown_impulse_ns: f32,

    /// Keep each punch's per-frame features, observations and actions for `last_punch_record` (set by analysis
    /// tools and tests through `PunchProbe`, debug builds only).
    record: bool,

    lifecycle: Lifecycle<Rc<PunchingPolicy>>,
    /// The character the running punch or recovery drives (a `character` set meanwhile waits for the next).
    driven: Option<Gd<PunchCharacter>>,
    aim: Option<Target>,
    area_query: Option<Gd<PhysicsShapeQueryParameters3D>>,
    /// This frame was sensed: the frame pass may act on it (a punch started by a signal handler in between
    /// waits for the next frame).
    sensed: bool,
    /// The controller is leaving the scene tree (a `punch_finished` handler may not start another punch).
    leaving_tree: bool,
    /// The controller is being freed (its events cannot wait for a frame).
    being_freed: bool,
    /// Its character was knocked down and hangs limp (motors off) until the next recovery or punch.
    down: bool,
    base: Base<Node>,
}

#[godot_api]
impl INode for PunchController {
    fn ready(&mut self) {
        if self.stance_pose {
            // Deferred: the character (often the controller's parent) is ready only after its children.
            self.base_mut().call_deferred("set_stance_pose", &[true.to_variant()]);
        }
        if self.autostart {
            self.base_mut().call_deferred("punch", &[]);
        }
    }

    fn on_notification(&mut self, what: NodeNotification) {
        match what {
            NodeNotification::ENTER_TREE => {
                self.leaving_tree = false;
                PunchControllerRegistry::set_in_tree(self.base().instance_id(), true, Self::react_to_hit);
            }
            // Leaving the tree: no frame will drive it, so the punch ends now. Its events wait for the next
            // frame pass, which emits them with no borrow held (a handler may free this controller), unless
            // the controller is being freed: then they go out now, as no frame will come.
            NodeNotification::EXIT_TREE => {
                self.leaving_tree = true;
                PunchControllerRegistry::set_in_tree(self.base().instance_id(), false, Self::react_to_hit);
                self.lifecycle.cancel();
                self.act_now();
                if self.being_freed {
                    self.emit_now();
                }
            }
            // Freed (itself, or with its scene after it left the tree): what it has not said yet goes out now,
            // unless the game is quitting (the whole tree is being torn down: nobody is left to tell, and
            // handlers would meet freed nodes).
            NodeNotification::PREDELETE => {
                self.being_freed = true;
                self.emit_now();
            }
            _ => {}
        }
    }
}

#[godot_api]
impl PunchController {
    /// `stance`: the left hand leads.
    #[constant]
    const ORTHODOX: i64 = 0;
    /// `stance`: the right hand leads.
    #[constant]
    const SOUTHPAW: i64 = 1;

    /// Emitted when a punch begins: the move (`&"jab"` ... `&"rear_uppercut"`; empty for `policy` thrown with no
    /// move), the hand that throws it (`&"left"` or `&"right"`), and its index in its string of punches (0: thrown
    /// on its own; 1, 2, ...: the punches that followed it from the queue, `combo()` or `punch()` during a punch).
    #[signal]
    fn punch_started(move_name: StringName, hand: StringName, combo_index: i64);

    /// Emitted when a punch starts with the target outside the policy's reach volume (`reach_volume()`), so
    /// it may miss. The punch still goes at the target while it is at most 0.3 m outside (policies reach a little
    /// past what they were trained on, and a bag swinging back comes within reach), else at the point 0.3 m out
    /// nearest to it. `offset` is where the target is in the character's frame (+Z ahead, +Y up, +X its left),
    /// `nearest` the nearest point the policy covers (global coordinates): move the character (or the target)
    /// so that the target's centre is there for a sure punch.
    #[signal]
    fn target_out_of_reach(offset: Vector3, nearest: Vector3);

    /// Emitted when a fist strikes something (the target, or a body on `hit_layers`), once per thing and
    /// punch (touching it again in the same punch is no new hit): `impulse` (N s) on it in that first
    /// frame, the striking fist's peak `speed` so far (m/s), where the fist was (`position`, global), what was hit
    /// (`body`: a CollisionObject3D, or null if it is gone), and `push`, the impulse vector (N s, global
    /// axes) for bodies that physics does not push, such as a CharacterBody3D:
    /// `enemy.velocity += push / enemy_mass_kg` knocks it back; the `hand` that struck (`&"left"` or
    /// `&"right"`: the punching one, or the guard hand); the `part` of a character struck (`&"head"`, `&"torso"`,
    /// `&"left_arm"` or `&"right_arm"`, as its `hit_taken` names it; empty when `body` is no character's), and
    /// whether the hit was `blocked`: it struck an arm, a guard in the way.
    #[signal]
    fn hit(
        impulse: f32,
        speed: f32,
        position: Vector3,
        body: Option<Gd<Node3D>>,
        push: Vector3,
        hand: StringName,
        part: StringName,
        blocked: bool,
    );

    /// Emitted when a punch is over, however it ended, with `move` and `hand` (as `punch_started` gave them),
    /// `frames`, `peak_fist_speed_mps` (the punching fist's; m/s), `peak_off_fist_speed_mps` (the guard hand's,
    /// m/s), `hits`,
    /// `strongest_hit_ns` (the largest fist impulse of one frame), `ended` ("completed"; "interrupted":
    /// cancelled, ended by `recover()`, taken over by another controller, or the controller left the scene tree before
    /// its last frame; "chained": ended at its cancel window for the next punch of a combo; "struck": its character
    /// was hit meanwhile (`react_to_hits`); "error": it stopped on an error, given in `error` and logged),
    /// `interrupted` (true unless completed), and `outcome`: "landed" (the punching fist struck something first
    /// that is not an arm), "blocked" (it struck a character's arm first) or "whiffed" (it struck nothing). Every `punch_started` is
    /// followed by exactly one `punch_finished`, so code waiting for it never waits forever.
    #[signal]
    fn punch_finished(metrics: VarDictionary);

    /// Emitted when the character is back in its guard pose after `recover()` (or a punch with
    /// `auto_recover`), or when the recovery's time is up. After a hit it waits for the head to rest on its neck too.
    #[signal]
    fn recovered();

    /// Emitted when its character is struck at least `stagger_impulse_ns` hard (and less than
    /// `knockdown_impulse_ns`), after the reaction began: the hit's `impulse_ns` (N s).
    #[signal]
    fn staggered(impulse_ns: f32);

    /// Emitted when its character is struck at least `knockdown_impulse_ns` hard: the punch has ended and the body
    /// hangs limp; `recover()` (or the next punch) brings it back to guard. `impulse_ns`: the hit's (N s).
    #[signal]
    fn knocked_down(impulse_ns: f32);

    /// Emitted after the last `punch_finished` of a string of punches (a punch and those that followed it from
    /// the queue; a punch on its own is a string of one): how many of them `landed` (the punching fist struck
    /// something) and how many were `thrown`. A string ends when its last punch ends with nothing waiting, or
    /// on `cancel()`, `recover()`, an error, or a punch started by a new string.
    #[signal]
    fn combo_finished(landed: i64, thrown: i64);

    /// Throws `move_name` ("jab", "cross", "lead_hook", "rear_hook", "lead_uppercut", "rear_uppercut") with
    /// the hand `stance` gives it, playing `moveset`'s policy for it; with no move, `default_move`, or when that
    /// is empty too, `policy` with the right hand. Asked for while a punch runs, the move waits (one deep: a later
    /// call replaces it) for the running punch's cancel window and then follows it (`combo()`); `cancel()` first
    /// to start one at once. A punch starts at once from the guard pose, else after a return to guard
    /// (`guard_first`) or from the current pose. Returns false (with the reason in the log) when the move is none of
    /// the six or the moveset has no policy for it, the controller is not in the scene tree, the policy, the
    /// character or the target is missing or unusable, or the project's physics settings are not the policy's. A
    /// target outside the policy's reach gets `target_out_of_reach`, and a punch at it (0.3 m out at most).
    #[func(gd_self)]
    fn punch(this: Gd<Self>, #[opt(default = "")] move_name: StringName) -> bool {
        Self::throw(this, &[move_name])
    }

    /// Throws `moves` one after another, a combination (`[&"jab", &"cross", &"lead_hook"]`): each starts at the
    /// one before's cancel window (`PunchMoveset`'s cancel delays), from wherever the arms are (or from guard,
    /// with `guard_first`). While a punch runs the whole string waits for its window, replacing what waited.
    /// Each punch has its own `punch_started` (with its index in the string) and `punch_finished`; `combo_finished`
    /// follows the last. Returns false (nothing thrown or queued, the reason in the log) when any move cannot be
    /// thrown, as `punch()` does.
    #[func(gd_self)]
    fn combo(this: Gd<Self>, moves: VarArray) -> bool {
        let names: Result<Vec<StringName>, String> = moves
            .iter_shared()
            .map(|name| {
                name.try_to::<StringName>()
                    .or_else(|_| name.try_to::<GString>().map(|name| StringName::from(&name)))
                    .map_err(|_| format!("combo() takes move names; {name} is not one"))
            })
            .collect();
        match names {
            Ok(names) => Self::throw(this, &names),
            Err(error) => {
                godot_error!("PunchController '{}': {error}", this.get_name());
                false
            }
        }
    }
    /// The hand (`&"left"` or `&"right"`) that throws `move_name` in `stance` (ORTHODOX or SOUTHPAW); empty when
    /// the move is none of the six. The left hand punches at the mirror image of where the right hand's policy
    /// aims: a target for it belongs on the character's left (+X) as a right-hand target on its right.
    #[func]
    fn hand_for(move_name: StringName, stance: PunchStance) -> StringName {
        Move::from_name(&move_name.to_string()).map_or(StringName::default(), |m| m.hand(stance.into()).name().into())
    }

    /// Ends the current punch (`punch_finished` reports it interrupted) or recovery; the joints then hold
    /// the pose they are in.
    #[func(gd_self)]
    fn cancel(mut this: Gd<Self>) {
        {
            let mut controller = this.bind_mut();
            controller.lifecycle.cancel();
            controller.act_now();
        }
        Self::emit_events(&mut this);
    }

    /// Drives the character back to its guard pose under physics (ending a punch that is running);
    /// `recovered` is emitted when it is there.
    #[func(gd_self)]
    fn recover(mut this: Gd<Self>) {
        let started = this.bind_mut().start_recovery();
        match started {
            Ok(character) => Self::take_over(&this, character),
            Err(error) => godot_error!("PunchController '{}': {error}", this.get_name()),
        }
        Self::emit_events(&mut this);
    }

    /// Raises a high guard now (both fists in front of the face, the trunk turned to face `target`, the opponent,
    /// and kept facing it every frame as either moves; docs/hits.md) and holds it for `seconds` (0 or less: until
    /// `stop_blocking()`), then goes back into the character's guard; no `recovered` either way. A running punch ends (interrupted; what was queued is
    /// dropped). A punch, `recover()` or `cancel()` ends the block too; a hit below `stagger_impulse_ns` does not
    /// (the arms give a little and rise again). Returns false, with the reason in the log, when there is no
    /// character to block with, it is knocked down, or `seconds` is not a number.
    #[func(gd_self)]
    fn block(mut this: Gd<Self>, #[opt(default = 0.0)] seconds: f32) -> bool {
        let started = this.bind_mut().start_block(seconds);
        let blocked = match started {
            Ok(character) => {
                Self::take_over(&this, character);
                true
            }
            Err(error) => {
                godot_error!("PunchController '{}': {error}", this.get_name());
                false
            }
        };
        Self::emit_events(&mut this);
        blocked
    }

    /// Ends a block now (`block()`): the character goes back into its guard. Does nothing when none holds.
    #[func]
    fn stop_blocking(&mut self) {
        self.lifecycle.lower_block();
    }

    /// True while a block holds its high guard (`block()`).
    #[func]
    fn is_blocking(&self) -> bool {
        self.lifecycle.is_blocking()
    }

    /// The target placements `punch(move_name)` covers (with no move: `default_move`'s, or `policy`'s), in the
    /// character's frame: `distance_m`, `height_m` and `side_m` ranges of the target's centre (Vector2(low, high);
    /// +Z ahead, +Y up, +X the character's left; a left-hand move's is the mirror image of its policy's),
    /// `max_target_speed_mps` and `any_start_pose` (false: only from the settled guard). Targets up to 3 cm outside
    /// still count. For a character whose arms are shorter than the simulated body's (`PunchCharacter.size_arms`,
    /// an own rig's) the far distance shrinks with the arm: no target beyond the farthest its hand reaches less the
    /// shortfall. Empty (with the reason in the log) when the move or its policy cannot be had.
    #[func]
    fn reach_volume(&self, #[opt(default = "")] move_name: StringName) -> VarDictionary {
        let mut result = VarDictionary::new();
        let reach = match self.throw_of(&move_name) {
            Ok(throw) => {
                let reach = live(&self.character).map_or(throw.policy.reach, |c| self.sized_reach(&throw, &c));
                if throw.hand.is_mirrored() { reach.mirrored() } else { reach }
            }
            Err(error) => {
                if !error.is_empty() {
                    godot_error!("PunchController '{}': {error}", self.base().get_name());
                }
                return result;
            }
        };
        for (key, [low, high]) in
            [("distance_m", reach.distance_m), ("height_m", reach.height_m), ("side_m", reach.side_m)]
        {
            result.set(key, Vector2::new(low, high));
        }
        result.set("max_target_speed_mps", reach.max_target_speed_mps);
        result.set("any_start_pose", reach.any_start_pose);
        result
    }

    /// True when a target centred at `position` (global) lies in the reach of `punch(move_name)` (with no move:
    /// `default_move`'s, or `policy`'s) from where the character stands now: the rule `punch()` checks before it
    /// says `target_out_of_reach`, with `reach_volume(move_name)`'s volume (3 cm outside still counts). A game's AI
    /// asks it to throw only what lands from here. False (with the reason in the log) when the move, its policy or
    /// the character cannot be had.
    #[func]
    fn reaches(&self, move_name: StringName, position: Vector3) -> bool {
        let checked = self.throw_of(&move_name).and_then(|throw| {
            let character = live(&self.character).ok_or("no character set (or it was freed)")?;
            let geometry = geometry_of(&character)?;
            Ok((throw, character, geometry))
        });
        match checked {
            Ok((throw, character, geometry)) => {
                let offset = policy_offset(&geometry, throw.hand, vec3(position));
                self.sized_reach(&throw, &character).contains(offset)
            }
            Err(error) => {
                if !error.is_empty() {
                    godot_error!("PunchController '{}': reaches(): {error}", self.base().get_name());
                }
                false
            }
        }
    }

    /// True while a punch is running (including its return to guard first, `guard_first`).
    #[func]
    pub fn is_punching(&self) -> bool {
        self.lifecycle.is_punching()
    }

    /// The moves waiting for the running punch's cancel window (`punch()` or `combo()` during a punch), in the order
    /// they will be thrown.
    #[func]
    fn queued_moves(&self) -> PackedStringArray {
        self.lifecycle.queued().map(GString::from).collect()
    }

    /// True from `knocked_down` until `recover()` or the next punch: the body hangs limp.
    #[func]
    fn is_knocked_down(&self) -> bool {
        self.down
    }

    /// True while the character returns to its guard pose.
    #[func]
    fn is_recovering(&self) -> bool {
        self.lifecycle.is_recovering()
    }

    /// Physics frames each decision is held for: the policy's (`decision_period`).
    #[func]
    fn get_decision_period(&self) -> i32 {
        self.punching_policy().map_or(DEFAULT_DECISION_PERIOD, |policy| policy.spec.decision_period) as i32
    }

    /// Sets the policy; the next punch plays it (a punch running now plays on with its own).
    #[func]
    fn set_policy(&mut self, policy: Option<Gd<PunchPolicy>>) {
        self.policy = policy;
    }

    /// Sets `stance`; with `stance_pose` on, an idle character turns into that stance's guard (no `recovered`).
    #[func]
    fn set_stance(&mut self, stance: PunchStance) {
        self.stance = stance;
        self.settle_into_guard();
    }

    /// Sets `stance_pose`; an idle character turns into the guard it gives (the stance's, or the square guard when
    /// off) at once, without a `recovered`.
    #[func]
    fn set_stance_pose(&mut self, stance_pose: bool) {
        self.stance_pose = stance_pose;
        self.settle_into_guard();
    }

    /// Sets `noise_sigma`: clamped to 0..1 with a warning; a value that is not a number is refused (the
    /// sigma stays as it was) with a warning.
    #[func]
    fn set_noise_sigma(&mut self, sigma: f32) {
        let name = self.base().get_name();
        if !sigma.is_finite() {
            godot_warn!(
                "PunchController '{name}': noise_sigma {sigma} is not a number in 0..1; keeping {}",
                self.noise_sigma
            );
            return;
        }
        let clamped = sigma.clamp(0.0, 1.0);
        if clamped != sigma {
            godot_warn!("PunchController '{name}': noise_sigma {sigma} is outside 0..1; using {clamped}");
        }
        self.noise_sigma = clamped;
    }
}

impl PunchController {
    /// Keeps each punch's per-frame features, observations and actions from the next punch on
    /// (`last_punch_record`), or stops keeping them.
    #[cfg(feature = "probe")]
    pub fn set_record(&mut self, record: bool) {
        self.record = record;
    }

    /// The last finished punch, when `record` is on: `features` (frames x feature count, the names are
    /// `PunchSpec.feature_names()`), `observations` (decisions x 45), `mean_actions` and `actions`
    /// (decisions x 10, before and after noise), `frames` and `decisions`.
    #[cfg(feature = "probe")]
    pub fn last_punch_record(&self) -> VarDictionary {
        use godot::builtin::PackedFloat32Array;
        use punch_core::contract::observation::OBS_DIM;
        use punch_core::contract::sensing::FEATURE_COUNT;

        let record = self.lifecycle.last_record();
        let mut result = VarDictionary::new();
        result.set("features", &PackedFloat32Array::from(record.features.as_slice()));
        result.set("observations", &PackedFloat32Array::from(record.observations.as_slice()));
        result.set("mean_actions", &PackedFloat32Array::from(record.mean_actions.as_slice()));
        result.set("actions", &PackedFloat32Array::from(record.actions.as_slice()));
        result.set("frames", (record.features.len() / FEATURE_COUNT) as i64);
        result.set("decisions", (record.observations.len() / OBS_DIM) as i64);
        result
    }

    /// What `punch(move_name)` throws: the move's policy from the moveset and its hand in the stance, or
    /// `policy` with the right hand when no move is named (here or in `default_move`).
    fn throw_of(&self, move_name: &StringName) -> Result<Throw, String> {
        let name = if move_name.is_empty() { self.default_move.to_string() } else { move_name.to_string() };
        if name.is_empty() {
            return Ok(Throw {
                policy: self.punching_policy()?,
                hand: Hand::Right,
                punch_move: None,
                cancel_delay_s: 0.0,
                guard_tolerance_rad: Recovery::READY_ANGLE_RAD,
            });
        }
        let punch_move = Move::from_name(&name).map_err(|error| error.to_string())?;
        let moveset = match &self.moveset {
            Some(moveset) => moveset.clone(),
            None => {
                let addon = if self.stance_pose { ADDON_STANCE_MOVESET } else { ADDON_MOVESET };
                try_load::<PunchMoveset>(addon)
                    .map_err(|error| format!("no moveset set, and the addon's ({addon}) does not load: {error}"))?
            }
        };
        let mut policy = moveset.bind().policy_of(punch_move).ok_or_else(|| {
            format!("the moveset '{}' has no policy for '{punch_move}': set one in its inspector", moveset.get_path())
        })?;
        let policy = policy.bind_mut().punching()?;
        let (cancel_delay_s, guard_tolerance_rad) =
            (moveset.bind().cancel_delay_s_of(punch_move), moveset.bind().guard_tolerance_rad_of(punch_move));
        let hand = punch_move.hand(self.stance.into());
        Ok(Throw { policy, hand, punch_move: Some(punch_move), cancel_delay_s, guard_tolerance_rad })
    }

    /// Throws `moves` one after another: while a punch runs (or moves wait for its cancel window) they replace
    /// what waited; else the first starts now and the others wait for it. Every move is checked first: one that
    /// cannot be thrown refuses them all. Returns the character a punch started now drives.
    fn ask(&mut self, moves: &[StringName]) -> Result<Option<Gd<PunchCharacter>>, String> {
        for name in moves {
            self.checked(name)?;
        }
        let names = moves.iter().map(StringName::to_string);
        if self.lifecycle.is_busy() {
            self.lifecycle.enqueue(names);
            return Ok(None);
        }
        let (first, rest) = moves.split_first().ok_or("no moves given")?;
        let character = self.start_punch(first)?;
        self.lifecycle.enqueue(rest.iter().map(StringName::to_string));
        Ok(Some(character))
    }

    /// Starts a punch now (its events queued); returns the character it drives.
    fn start_punch(&mut self, move_name: &StringName) -> Result<Gd<PunchCharacter>, String> {
        let Prepared { start, identity, character } = self.prepare(move_name)?;
        self.lifecycle.start(start, identity, self.noise());
        self.drive_from_now(character.clone());
        Ok(character)
    }

    /// Starts the queued move due now, chained to the punch before it (in the frame pass, before the frame is
    /// sensed); one that cannot be thrown is dropped, with the reason in the log.
    fn chain_due(&mut self) {
        let Some(name) = self.lifecycle.due().map(StringName::from) else { return };
        let prepared = self.prepare(&name).and_then(|Prepared { start, identity, character }| {
            match live(&self.driven).is_some_and(|driven| driven == character) {
                true => Ok((start, identity)),
                false => Err("the controller's character changed during the combo".to_string()),
            }
        });
        match prepared {
            Ok((start, identity)) => self.lifecycle.chain(start, identity, self.noise()),
            Err(error) => {
                godot_error!("PunchController '{}': the queued '{name}' is dropped: {error}", self.base().get_name());
                self.lifecycle.drop_due();
            }
        }
    }

    /// The reach of `throw` for the controller's character: its policy's, shrunk for arms shorter than the
    /// simulated body's (`ReachVolume::within_arm`; the lead hand's range from the stance's guard lies further ahead).
    fn sized_reach(&self, throw: &Throw, character: &Gd<PunchCharacter>) -> ReachVolume {
        let lead_from_stance = self.stance_pose && throw.punch_move.is_some_and(|m| m.side() == Side::Lead);
        let hand_far_m = hand_far_m(lead_from_stance).max(throw.policy.reach.distance_m[1]);
        throw.policy.reach.within_arm(hand_far_m, character.bind().arm_shortfall_m())
    }

    /// What `punch(move_name)` would throw, and at which character and target, when it can be thrown now (the
    /// reason when not).
    fn checked(&self, move_name: &StringName) -> Result<Checked, String> {
        if !self.base().is_inside_tree() || self.leaving_tree {
            return Err("the controller is not in the scene tree: add it to the scene before punching (punches \
                        run on the scene tree's physics frames)"
                .into());
        }
        PunchControllerRegistry::check_project_settings()?;
        let throw = self.throw_of(move_name)?;
        throw.policy.check_spec(throw.policy.spec.decision_period).map_err(|e| e.to_string())?;
        let character = live(&self.character).ok_or("no character set (or it was freed)")?;
        let target = Target::resolve(live(&self.target).ok_or("no target set (or it was freed)")?);
        let geometry = geometry_of(&character)?;
        let target_position = target.state()?.position;
        Ok(Checked { throw, character, target, geometry, target_position })
    }

    /// The start of `move_name`'s punch of the controller's character at its target (aimed at from now on).
    fn prepare(&mut self, move_name: &StringName) -> Result<Prepared, String> {
        let Checked { throw, character, mut target, mut geometry, target_position } = self.checked(move_name)?;
        let reach = self.sized_reach(&throw, &character);
        let Throw { policy, hand, punch_move, cancel_delay_s, guard_tolerance_rad } = throw;
        self.lifecycle.set_guard(self.guard_targets());
        let offset = policy_offset(&geometry, hand, target_position);
        let out_of_reach = (!reach.contains(offset)).then(|| {
            // Back from the policy's frame (a mirror is its own inverse) to the world's.
            let to_local = |policy: Vec3| if hand.is_mirrored() { mirror_point(policy) } else { policy };
            let world = |policy: Vec3| geometry.root_position + geometry.root_rotation * to_local(policy);
            // A little out, the policy sees the target itself; far out, the point of its margin nearest to it.
            let aim = reach.aim_point(offset);
            if aim != offset {
                target.aim_at(world(aim));
            }
            (to_local(offset), world(reach.nearest(offset)))
        });
        target.describe(&mut geometry);
        self.aim = Some(target);
        let punch = Punch::new(geometry, policy.spec, self.record)
            .with_noise_scale(policy.noise_scale)
            .with_hand(hand)
            .with_move(punch_move);
        let identity = Rc::as_ptr(&policy) as usize;
        let ticks_per_s = Engine::singleton().get_physics_ticks_per_second() as f32;
        let cancel_delay_frames = (cancel_delay_s * ticks_per_s).round() as u32;
        // A policy trained from a load (its `punch_start_load`) punches from there alone: the arm is drawn into it
        // first, with or without `guard_first`.
        let start_pose = policy.start_load.map(|load| load.loaded_for(self.guard_targets(), hand.is_mirrored()));
        let guard_first = (self.guard_first || start_pose.is_some()).then_some(guard_tolerance_rad);
        let start = PunchStart { punch, policy, guard_first, start_pose, out_of_reach, cancel_delay_frames };
        Ok(Prepared { start, identity, character })
    }

    /// Starts a block of `seconds` (0 or less: until stopped); returns the character it drives.
    fn start_block(&mut self, seconds: f32) -> Result<Gd<PunchCharacter>, String> {
        if !seconds.is_finite() {
            return Err(format!("block({seconds}): the seconds must be a number"));
        }
        if self.down {
            return Err("the character is knocked down: it blocks once recover() (or a punch) brought it back".into());
        }
        let character = live(&self.character).ok_or("no character set (or it was freed)")?;
        let geometry = geometry_of(&character)?;
        if !self.base().is_inside_tree() || self.leaving_tree {
            return Err("the controller is not in the scene tree".into());
        }
        let ticks_per_s = Engine::singleton().get_physics_ticks_per_second() as f32;
        let frames = (seconds > 0.0).then(|| (seconds * ticks_per_s).round().max(1.0) as u32);
        self.lifecycle.set_guard(self.guard_targets());
        let high_guard = self.high_guard(&character, &geometry);
        self.lifecycle.block(geometry, high_guard, frames);
        self.drive_from_now(character.clone());
        Ok(character)
    }

    /// A block's guard for `character` standing as `geometry` says: the high guard, its trunk facing the target (the
    /// opponent) so the shell meets its punches square on. An own rig's head may sit higher on its neck: the gloves
    /// rise with it.
    fn high_guard(&self, character: &Gd<PunchCharacter>, geometry: &CharacterGeometry) -> [f32; DOF_COUNT] {
        let high_guard = high_guard_rad(character.bind().head_shift_m());
        match live(&self.target) {
            Some(target) => {
                let local = geometry.root_local(vec3(target.get_global_position()));
                turned_toward(high_guard, local.x.atan2(local.z))
            }
            None => high_guard,
        }
    }

    /// Starts a recovery; returns the character it drives.
    fn start_recovery(&mut self) -> Result<Gd<PunchCharacter>, String> {
        let character = live(&self.character).ok_or("no character set (or it was freed)")?;
        let geometry = geometry_of(&character)?;
        if !self.base().is_inside_tree() || self.leaving_tree {
            return Err("the controller is not in the scene tree".into());
        }
        self.lifecycle.set_guard(self.guard_targets());
        self.lifecycle.recover(geometry);
        self.drive_from_now(character.clone());
        Ok(character)
    }

    /// Puts this controller on the frame pass's list, driving `character`.
    fn drive_from_now(&mut self, character: Gd<PunchCharacter>) {
        // Motors on: a knock-down (by this controller or another) may have left them off.
        self.down = false;
        if let Some(rig) = character.bind().rig() {
            rig.set_limp(false);
        }
        self.driven = Some(character);
        self.sensed = false;
        let tree = self.base().get_tree();
        PunchControllerRegistry::enlist(self.base().instance_id(), tree, Self::frame_pass);
    }

    /// `this` drives `character` from now on: another controller that drove it stops, its punch ending
    /// (interrupted), with a warning.
    fn take_over(this: &Gd<Self>, character: Gd<PunchCharacter>) {
        let Some(previous) = PunchControllerRegistry::take_over(character.instance_id(), this.instance_id()) else {
            return;
        };
        let Ok(mut other) = Gd::<Self>::try_from_instance_id(previous) else { return };
        let was_punching = other.bind().lifecycle.is_punching();
        if !other.bind().lifecycle.is_active() || other.bind().driven.as_ref() != Some(&character) {
            return;
        }
        if was_punching {
            godot_warn!(
                "PunchController '{}' takes character '{}' over from '{}', whose punch ends (interrupted): drive each \
                 character with one controller at a time",
                this.get_name(),
                character.get_name(),
                other.get_name()
            );
        }
        {
            let mut other = other.bind_mut();
            other.lifecycle.cancel();
            other.act_now();
        }
        Self::emit_events(&mut other);
    }

    /// `character` was struck `impulse_ns` hard (`PunchCharacter`'s `hit_taken`, which `from` caused: another
    /// controller, or nothing for the game's `take_hit`): the controller in the tree that drives it (or has it as its
    /// `character`) reacts, as `react_to_hits`, `hyper_armour` and the thresholds say, and says what that ended.
    fn react_to_hit(character: InstanceId, from: Option<InstanceId>, impulse_ns: f32) {
        let Ok(character) = Gd::<PunchCharacter>::try_from_instance_id(character) else { return };
        let character = &character;
        let mine = |controller: &Gd<Self>| {
            let controller = controller.bind();
            let driven = controller.lifecycle.is_active() && controller.driven.as_ref() == Some(character);
            (driven, controller.character.as_ref() == Some(character))
        };
        let controllers: Vec<Gd<Self>> = PunchControllerRegistry::in_tree()
            .into_iter()
            .filter(|id| Some(*id) != from)
            .filter_map(|id| Gd::<Self>::try_from_instance_id(id).ok())
            .collect();
        let chosen = controllers.iter().find(|c| mine(c).0).or_else(|| controllers.iter().find(|c| mine(c).1));
        let Some(mut controller) = chosen.cloned() else { return };
        let reaction = controller.bind_mut().react(character, impulse_ns);
        Self::emit_events(&mut controller);
        if !controller.is_instance_valid() {
            return;
        }
        match reaction {
            // Unless a handler of the punch's end already brought it back (a punch, `recover()`).
            Some(Reaction::KnockedDown) if controller.bind().down => {
                controller.signals().knocked_down().emit(impulse_ns)
            }
            Some(Reaction::Staggered) => controller.signals().staggered().emit(impulse_ns),
            _ => {}
        }
    }

    /// Ends or keeps the punch and starts the way back to guard, or lets the body go limp; None when it does not react.
    fn react(&mut self, character: &Gd<PunchCharacter>, impulse_ns: f32) -> Option<Reaction> {
        if !self.react_to_hits || !self.base().is_inside_tree() || self.leaving_tree {
            return None;
        }
        if self.down {
            return None; // down stays down, however it is struck, until the game brings it back
        }
        // A hit given as 60 N s arrives as 59.9999 after the engine's float math: it still reaches a 60 N s threshold.
        let reaches = |threshold: f32| impulse_ns >= threshold * (1.0 - 1e-4);
        if self.lifecycle.is_blocking() && !reaches(self.stagger_impulse_ns) {
            return Some(Reaction::Flinched); // the block holds: its guard drives the arms back up
        }
        let geometry = geometry_of(character).ok()?;
        let guard = self.guard_targets();
        self.lifecycle.set_guard(guard);
        if reaches(self.knockdown_impulse_ns) {
            self.lifecycle.struck(geometry, false);
            self.lifecycle.cancel(); // no way back to guard: it hangs until the game says
            if let Some(rig) = character.bind().rig() {
                rig.set_limp(true);
            }
            self.down = true;
            return Some(Reaction::KnockedDown);
        }
        self.lifecycle.struck(geometry, self.hyper_armour);
        if !self.lifecycle.is_punching() {
            self.drive_from_now(character.clone()); // the way back to guard
        }
        Some(if reaches(self.stagger_impulse_ns) { Reaction::Staggered } else { Reaction::Flinched })
    }

    /// The policy resource as a checked punching policy (an empty error: refused and reported before).
    fn punching_policy(&self) -> Result<Rc<PunchingPolicy>, String> {
        let mut policy = self.policy.clone().ok_or("no policy set")?;
        policy.bind_mut().punching()
    }

    /// Drives an idle character in the tree into the guard `stance` and `stance_pose` give, quietly (a punch or
    /// recovery running, a knocked-down body, or a character another controller drives now keeps what it has until
    /// the next).
    fn settle_into_guard(&mut self) {
        if !self.base().is_inside_tree() || self.leaving_tree || self.down || self.lifecycle.is_active() {
            return;
        }
        let Some(character) = live(&self.character) else { return };
        let me = self.base().instance_id();
        if PunchControllerRegistry::driver_of(character.instance_id()).is_some_and(|driver| driver != me) {
            return;
        }
        let Ok(geometry) = geometry_of(&character) else { return };
        self.lifecycle.set_guard(self.guard_targets());
        self.lifecycle.settle(geometry);
        PunchControllerRegistry::take_over(character.instance_id(), me);
        self.drive_from_now(character);
    }

    /// The guard recoveries drive to: the stance's (`stance_pose`), or the square guard.
    fn guard_targets(&self) -> [f32; DOF_COUNT] {
        if self.stance_pose { Stance::from(self.stance).guard_targets() } else { [0.0; DOF_COUNT] }
    }

    fn noise(&self) -> NoiseSettings {
        NoiseSettings { seed: self.seed, sigma: self.noise_sigma, noisy_decisions: self.noise_decisions }
    }

    /// Applies at once what the lifecycle asks of the joints (after a punch or recovery ended outside the
    /// frame pass).
    fn act_now(&mut self) {
        if !self.lifecycle.is_punching() {
            let drive = self.lifecycle.act(None, self.noise()).unwrap_or(Drive::Hold);
            self.apply(drive);
        }
    }

    fn apply(&self, drive: Drive) {
        let Some(character) = live(&self.driven) else { return };
        let character = character.bind();
        let Some(rig) = character.rig() else { return };
        // A block's guard holds braced; anything else with the motors' own torques.
        rig.set_braced(self.lifecycle.is_blocking());
        match drive {
            Drive::Nothing => {}
            Drive::Motors(commands) => rig.drive(&commands),
            Drive::Hold => rig.drive(&[Vec3::ZERO; 5]),
        }
    }

    /// Runs every active controller for one physics frame (on the scene tree's `physics_frame` signal, before
    /// any node's `_physics_process`): each reads the frame just simulated, then every shared policy decides
    /// once for all controllers that ask it, then each drives its joints and emits its signals.
    fn frame_pass() {
        let started = Instant::now();
        let Some(ids) = PunchControllerRegistry::begin_frame(started) else { return };
        let mut requests: Vec<DecisionRequest> = Vec::new();
        let mut askers: Vec<InstanceId> = Vec::new();
        for &id in &ids {
            if let Some(mut controller) = running(id)
                && let Some(request) = controller.bind_mut().sense_frame()
            {
                askers.push(id);
                requests.push(request);
            }
        }
        let batch = decide_batched(&requests);
        let mut reported = Vec::new();
        for error in batch.means.iter().filter_map(|mean| mean.as_ref().err()) {
            if !reported.iter().any(|r| Rc::ptr_eq(r, error)) {
                // Once for the policy, not once per controller that asked it; each of their punches ends.
                let count = batch.means.iter().filter(|m| m.as_ref().is_err_and(|e| Rc::ptr_eq(e, error))).count();
                godot_error!("PunchController: inference failed for {count} controllers: {error}");
                reported.push(error.clone());
            }
        }
        for &id in &ids {
            if let Some(mut controller) = running(id) {
                let mean = askers.iter().position(|asker| *asker == id).map(|row| batch.means[row].clone());
                controller.bind_mut().act_frame(mean);
            }
            // Also what a controller that left the tree (or is paused) has to say.
            if let Ok(mut controller) = Gd::<Self>::try_from_instance_id(id) {
                Self::emit_events(&mut controller);
            }
        }
        PunchControllerRegistry::retain_active(|id| {
            Gd::<Self>::try_from_instance_id(id).is_ok_and(|controller| controller.bind().lifecycle.is_active())
        });
        PunchControllerRegistry::count_frame(started, &batch.calls);
    }

    /// First half of a frame: reads the frame just simulated and, when a decision is due, returns the
    /// observation to decide on (with the policy to ask). An error ends the punch.
    fn sense_frame(&mut self) -> Option<DecisionRequest> {
        self.sensed = true;
        match self.try_sense() {
            Ok(request) => request,
            Err(error) => {
                if self.lifecycle.is_punching() {
                    godot_error!("PunchController '{}': {error}; the punch stops", self.base().get_name());
                }
                self.lifecycle.fail(&error);
                None
            }
        }
    }

    fn try_sense(&mut self) -> Result<Option<DecisionRequest>, String> {
        self.chain_due();
        let character = live(&self.driven).ok_or("the character was freed")?;
        // Mirrored mid-punch (a game flipping its model): its left and right are no longer the policy's. Scale 0
        // or NaN only hold the body where it stood (`PunchCharacter` says so once), so the punch plays on.
        if let Err(cause @ TransformError::Mirrored) = rigid(character.get_global_transform()) {
            return Err(transform_problem(&character, cause));
        }
        // A block's trunk keeps facing the opponent as either moves (the shell square on).
        if self.lifecycle.is_blocking()
            && let Ok(geometry) = geometry_of(&character)
        {
            let high_guard = self.high_guard(&character, &geometry);
            self.lifecycle.turn_block(high_guard);
        }
        let character = character.bind();
        let rig = character.rig().ok_or("the character is not ready")?;
        let mut reading = FrameReading { bodies: rig.read_bodies()?, ..FrameReading::default() };
        if self.lifecycle.begin_frame(&reading) == FrameNeeds::Nothing {
            return Ok(None);
        }
        let aim = self.aim.as_ref().filter(|aim| aim.is_valid()).ok_or("the target was freed")?;
        reading.bag = aim.state()?;
        let mut touches = Vec::new();
        if let Some(state) = aim.reported_contacts() {
            add_bag_contacts(state, &rig.body_rids, &mut reading);
        }
        let (target_rid, reports) = (aim.body_rid(), aim.reported_contacts().is_some());
        read_forearm_contacts(&rig.forearm_states, target_rid, reports, self.hit_layers, &mut reading, &mut touches);
        if (self.hit_areas || aim.area().is_some())
            && let Some([right, left]) = self.lifecycle.fists(&reading)
        {
            let mask = self.hit_layers | aim.area().map_or(0, |area| area.get_collision_layer());
            let fists = [(Body::ForearmR.index(), right.0), (Body::ForearmL.index(), left.0)];
            let query = self.area_query.get_or_insert_with(|| fist_query(rig.geometry.fist_radius_m));
            if let Some(mut space) = character.base().get_world_3d().and_then(|w| w.get_direct_space_state()) {
                add_area_touches(&mut space, query, fists, mask, &mut touches);
            }
        }
        let recover_at = self.auto_recover.then(|| character.standing().map(|root| rig.geometry_at(root))).flatten();
        Ok(self.lifecycle.sense(reading, &touches, || recover_at).map(|(policy, observation)| (policy, *observation)))
    }

    /// Second half of a frame: takes the decision's mean action (when one was due; an error of its
    /// inference, logged by the frame pass, ends the punch), adds the noise, and drives the joints.
    fn act_frame(&mut self, mean: Option<Result<Vec<f32>, Rc<punch_core::CoreError>>>) {
        if !std::mem::take(&mut self.sensed) {
            return; // started after this frame was read: it plays from the next frame
        }
        let mean = match mean {
            Some(Err(error)) => {
                self.lifecycle.fail(&error.to_string());
                None
            }
            Some(Ok(mean)) => Some(mean),
            None => None,
        };
        let drive = match self.lifecycle.act(mean.as_deref(), self.noise()) {
            Ok(drive) => drive,
            Err(error) => {
                godot_error!("PunchController '{}': {error}; the punch stops", self.base().get_name());
                Drive::Hold
            }
        };
        self.apply(drive);
    }

    /// Emits the queued events from inside the controller (it is being freed, so no frame pass will), unless
    /// the scene tree is being torn down as the game quits.
    fn emit_now(&mut self) {
        if tree_is_quitting() {
            return;
        }
        while let Some(event) = self.lifecycle.next_event() {
            let from = self.base().instance_id();
            emit(self.signals(), event, from);
        }
    }

    /// `punch()` and `combo()`: throws or queues `moves`, then says what that started.
    fn throw(mut this: Gd<Self>, moves: &[StringName]) -> bool {
        let asked = this.bind_mut().ask(moves);
        let thrown = match asked {
            Ok(started) => {
                if let Some(character) = started {
                    Self::take_over(&this, character);
                }
                true
            }
            Err(error) => {
                if !error.is_empty() {
                    godot_error!("PunchController '{}': {error}", this.get_name());
                }
                false
            }
        };
        Self::emit_events(&mut this);
        thrown
    }

    /// Emits the controller's queued events one at a time, with no borrow held, so that a handler may do
    /// anything (its own events then follow in order). Stops when a handler freed the controller.
    fn emit_events(this: &mut Gd<Self>) {
        loop {
            if !this.is_instance_valid() {
                return;
            }
            let Some(event) = this.bind_mut().lifecycle.next_event() else { return };
            let from = this.instance_id();
            emit(this.signals(), event, from);
        }
    }
}

/// Emits one event as its signal; `from` is the controller whose event it is.
fn emit(mut signals: Signals<'_>, event: Event, from: InstanceId) {
    match event {
        Event::Started { hand, punch_move, combo_index } => {
            signals.punch_started().emit(&move_name_of(punch_move), &StringName::from(hand.name()), combo_index as i64)
        }
        Event::OutOfReach { offset, nearest } => signals.target_out_of_reach().emit(vector3(offset), vector3(nearest)),
        Event::Hit(hit) => {
            let body = Gd::<Node3D>::try_from_instance_id(InstanceId::from_i64(hit.collider as i64)).ok();
            let part = body.as_ref().and_then(PunchCharacter::part_of_body);
            signals.hit().emit(
                hit.impulse_ns(),
                hit.speed_mps,
                vector3(hit.position),
                body.as_ref(),
                vector3(hit.impulse),
                &StringName::from(hit.hand.name()),
                &StringName::from(part.map_or("", |part| part.name())),
                part.is_some_and(|part| part.is_arm()),
            );
            // A body of another character: it is told, and its controller reacts.
            if let Some(body) = body {
                PunchCharacter::struck_by_fist(body, vector3(hit.impulse), vector3(hit.position), from);
            }
        }
        Event::Finished(summary, ending) => signals.punch_finished().emit(&finish_metrics(&summary, &ending)),
        Event::Recovered => signals.recovered().emit(),
        Event::ComboFinished { landed, thrown } => signals.combo_finished().emit(landed as i64, thrown as i64),
    }
}

/// True while the game's scene tree is being torn down (its root has left the tree: the game quits).
fn tree_is_quitting() -> bool {
    let tree = Engine::singleton().get_main_loop().and_then(|main_loop| main_loop.try_cast::<SceneTree>().ok());
    tree.and_then(|tree| tree.get_root()).is_none_or(|root| !root.is_inside_tree())
}

/// The controller with this id, if it still exists and is processing (not paused).
fn running(id: InstanceId) -> Option<Gd<PunchController>> {
    Gd::<PunchController>::try_from_instance_id(id).ok().filter(|controller| controller.can_process())
}

/// The node if it is set and not freed (cloning a freed node's handle would panic).
fn live<T: GodotClass>(node: &Option<Gd<T>>) -> Option<Gd<T>> {
    node.as_ref().filter(|n| n.is_instance_valid()).cloned()
}

/// The character's rest geometry where it stands now.
fn geometry_of(character: &Gd<PunchCharacter>) -> Result<CharacterGeometry, String> {
    // A mirrored body's left and right are not the policy's, and a body without size or with a NaN has no frame:
    // none can land, so say why instead of punching into nothing.
    let root = rigid(character.get_global_transform()).map_err(|cause| transform_problem(character, cause))?;
    let geometry = character.bind().rig().map(|rig| rig.geometry_at(root));
    geometry.ok_or_else(|| "the character is not ready (is it in the scene tree?)".into())
}

/// Where `position` (global) lies from the character in the policy's frame: its root's, mirrored for a left-hand
/// move (the reach volume is the right hand's; the left hand's is its mirror image).
fn policy_offset(geometry: &CharacterGeometry, hand: Hand, position: Vec3) -> Vec3 {
    let local = geometry.root_local(position);
    if hand.is_mirrored() { mirror_point(local) } else { local }
}

/// What is wrong with the character's transform, and what to do.
fn transform_problem(character: &Gd<PunchCharacter>, cause: TransformError) -> String {
    let name = character.get_name();
    match cause {
        TransformError::Mirrored => format!(
            "character '{name}' is mirrored (a negative scale on it or a parent): its left and right are no longer \
             the policy's, so it cannot land; use the other stance (the other hand) instead of a mirrored model, and \
             face it the other way with a rotation instead of a negative scale"
        ),
        TransformError::NotFinite => format!(
            "character '{name}''s transform (or a parent's) is not a number (NaN or infinite): give it a valid \
             transform before it punches"
        ),
        TransformError::NoSize | TransformError::ZeroRotation => format!(
            "character '{name}' has no size (a scale of 0 on it or a parent): give it (and its parents) a scale \
             that is not 0 before it punches"
        ),
    }
}

/// A sphere query of the fist's size for overlapping areas.
fn fist_query(radius_m: f32) -> Gd<PhysicsShapeQueryParameters3D> {
    let mut sphere = SphereShape3D::new_gd();
    sphere.set_radius(radius_m);
    let mut query = PhysicsShapeQueryParameters3D::new_gd();
    query.set_shape(&sphere);
    query.set_collide_with_areas(true);
    query.set_collide_with_bodies(false);
    query
}

/// A move's name as signals carry it (empty for a policy thrown with no move).
fn move_name_of(punch_move: Option<Move>) -> StringName {
    StringName::from(punch_move.map_or("", Move::name))
}

/// What became of a punch whose fist first struck `first_struck`: `"whiffed"` (nothing), `"blocked"` (an arm of a
/// character) or `"landed"` (anything else).
fn outcome(first_struck: Option<u64>) -> &'static str {
    let Some(collider) = first_struck else { return "whiffed" };
    let body = Gd::<Node3D>::try_from_instance_id(InstanceId::from_i64(collider as i64)).ok();
    match body.and_then(|body| PunchCharacter::part_of_body(&body)) {
        Some(part) if part.is_arm() => "blocked",
        _ => "landed",
    }
}

fn finish_metrics(summary: &PunchSummary, ending: &Ending) -> VarDictionary {
    let mut metrics = VarDictionary::new();
    metrics.set("move", &move_name_of(summary.punch_move));
    metrics.set("hand", &StringName::from(summary.hand.name()));
    let (ended, error) = match ending {
        Ending::Completed => ("completed", ""),
        Ending::Interrupted => ("interrupted", ""),
        Ending::Struck => ("struck", ""),
        Ending::Chained => ("chained", ""),
        Ending::Error(error) => ("error", error.as_str()),
    };
    metrics.set("ended", ended);
    metrics.set("outcome", outcome(summary.first_struck));
    if !error.is_empty() {
        metrics.set("error", error);
    }
    metrics.set("frames", summary.frames as i64);
    metrics.set("peak_fist_speed_mps", summary.peak_fist_speed_mps);
    metrics.set("peak_off_fist_speed_mps", summary.peak_off_fist_speed_mps);
    metrics.set("hits", summary.hits);
    metrics.set("strongest_hit_ns", summary.strongest_hit_ns);
    metrics.set("interrupted", summary.interrupted);
    metrics
}
