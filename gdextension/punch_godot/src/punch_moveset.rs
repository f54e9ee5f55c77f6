//! `PunchMoveset`: the policy of each of the six moves a `PunchController` throws by name.

use godot::builtin::{PackedStringArray, StringName};
use godot::classes::{IResource, Resource};
use godot::obj::{Base, Gd};
use godot::prelude::{GodotClass, godot_api};
use punch_core::game::moves::Move;
use punch_core::game::punch::Recovery;

use crate::punch_policy::PunchPolicy;

/// The policies of a boxer's six punches, by name: `PunchController.punch(&"jab")` plays this moveset's `jab`.
/// Each policy punches with the right hand; the controller's `stance` says which hand throws a move, and the left
/// hand plays the policy mirrored, so one policy serves both stances. The addon's moveset is
/// `res://addons/punch_controller/policies/boxing.tres`; duplicate it (or make a new one) to swap in a policy of
/// your own for a move. A move left empty is refused by `punch()`, naming it. Each move's cancel window (when a
/// move queued during it starts) and how near the guard it starts (with the controller's `guard_first`) are set
/// here too.
#[derive(GodotClass)]
#[class(base = Resource, init, tool)]
pub struct PunchMoveset {
    /// 1, the jab: the lead hand's straight, the quickest punch.
    #[export]
    jab: Option<Gd<PunchPolicy>>,
    /// 2, the cross: the rear hand's straight.
    #[export]
    cross: Option<Gd<PunchPolicy>>,
    /// 3, the lead hook: the lead fist swung in from the side, the elbow bent.
    #[export]
    lead_hook: Option<Gd<PunchPolicy>>,
    /// 4, the rear hook.
    #[export]
    rear_hook: Option<Gd<PunchPolicy>>,
    /// 5, the lead uppercut: the lead fist rising into the target.
    #[export]
    lead_uppercut: Option<Gd<PunchPolicy>>,
    /// 6, the rear uppercut.
    #[export]
    rear_uppercut: Option<Gd<PunchPolicy>>,

    /// The jab's cancel window: a move asked for during a jab (`PunchController.punch` or `combo`) starts this long
    /// after the jab's fist first lands (or after its last frame, when it lands nothing), in seconds. 0: at contact,
    /// the quickest combination; longer lets the fist come back first.
    #[export_group(name = "Cancel windows")]
    #[export(range = (0.0, 1.0, 0.01, or_greater, suffix = "s"))]
    jab_cancel_delay_s: f32,
    /// The cross's cancel window (as `jab_cancel_delay_s`), in seconds.
    #[export(range = (0.0, 1.0, 0.01, or_greater, suffix = "s"))]
    cross_cancel_delay_s: f32,
    /// The lead hook's cancel window (as `jab_cancel_delay_s`), in seconds.
    #[export(range = (0.0, 1.0, 0.01, or_greater, suffix = "s"))]
    lead_hook_cancel_delay_s: f32,
    /// The rear hook's cancel window (as `jab_cancel_delay_s`), in seconds.
    #[export(range = (0.0, 1.0, 0.01, or_greater, suffix = "s"))]
    rear_hook_cancel_delay_s: f32,
    /// The lead uppercut's cancel window (as `jab_cancel_delay_s`), in seconds.
    #[export(range = (0.0, 1.0, 0.01, or_greater, suffix = "s"))]
    lead_uppercut_cancel_delay_s: f32,
    /// The rear uppercut's cancel window (as `jab_cancel_delay_s`), in seconds.
    #[export(range = (0.0, 1.0, 0.01, or_greater, suffix = "s"))]
    rear_uppercut_cancel_delay_s: f32,

    /// How near its guard the jab starts when asked for away from it (with the controller's `guard_first`: the end of
    /// an earlier punch, mid-recovery, a combination's next punch): the body first returns until every joint is
    /// within this angle of its guard angle (and slower than ten times it per second; at most 0.5 s). Larger starts
    /// sooner, smaller lands more often (docs/combos.md). Shown in degrees, stored in radians.
    #[export_group(name = "Returns to guard")]
    #[export(range = (0.0, 0.5, 0.005, radians_as_degrees))]
    #[init(val = Recovery::READY_ANGLE_RAD)]
    jab_guard_tolerance_rad: f32,
    /// The cross's (as `jab_guard_tolerance_rad`).
    #[export(range = (0.0, 0.5, 0.005, radians_as_degrees))]
    #[init(val = Recovery::READY_ANGLE_RAD)]
    cross_guard_tolerance_rad: f32,
    /// The lead hook's (as `jab_guard_tolerance_rad`).
    #[export(range = (0.0, 0.5, 0.005, radians_as_degrees))]
    #[init(val = Recovery::READY_ANGLE_RAD)]
    lead_hook_guard_tolerance_rad: f32,
    /// The rear hook's (as `jab_guard_tolerance_rad`).
    #[export(range = (0.0, 0.5, 0.005, radians_as_degrees))]
    #[init(val = Recovery::READY_ANGLE_RAD)]
    rear_hook_guard_tolerance_rad: f32,
    /// The lead uppercut's (as `jab_guard_tolerance_rad`): settled by default (the guard `recovered` waits for), as
    /// an uppercut begins from under the fist and lands less often from a guard still moving.
    #[export(range = (0.0, 0.5, 0.005, radians_as_degrees))]
    #[init(val = Recovery::SETTLED_ANGLE_RAD)]
    lead_uppercut_guard_tolerance_rad: f32,
    /// The rear uppercut's (as `lead_uppercut_guard_tolerance_rad`).
    #[export(range = (0.0, 0.5, 0.005, radians_as_degrees))]
    #[init(val = Recovery::SETTLED_ANGLE_RAD)]
    rear_uppercut_guard_tolerance_rad: f32,
    base: Base<Resource>,
}

#[godot_api]
impl IResource for PunchMoveset {}

#[godot_api]
impl PunchMoveset {
    /// The policy of the move named `move_name` ("jab", "cross", "lead_hook", "rear_hook", "lead_uppercut",
    /// "rear_uppercut"), or null when the moveset has none for it or the name is none of the six.
    #[func]
    fn policy_for(&self, move_name: StringName) -> Option<Gd<PunchPolicy>> {
        Move::from_name(&move_name.to_string()).ok().and_then(|m| self.policy_of(m))
    }

    /// The names of the moves this moveset has a policy for, in boxing's order (1 to 6).
    #[func]
    fn moves(&self) -> PackedStringArray {
        Move::ALL.into_iter().filter(|&m| self.policy_of(m).is_some()).map(|m| m.name().into()).collect()
    }
}

impl PunchMoveset {
    /// The policy of `punch_move`, if the moveset has one.
    pub fn policy_of(&self, punch_move: Move) -> Option<Gd<PunchPolicy>> {
        match punch_move {
            Move::Jab => &self.jab,
            Move::Cross => &self.cross,
            Move::LeadHook => &self.lead_hook,
            Move::RearHook => &self.rear_hook,
            Move::LeadUppercut => &self.lead_uppercut,
            Move::RearUppercut => &self.rear_uppercut,
        }
        .clone()
    }

    /// How long after `punch_move`'s contact (or last frame) its cancel window opens, s (never negative).
    pub fn cancel_delay_s_of(&self, punch_move: Move) -> f32 {
        let delay_s = match punch_move {
            Move::Jab => self.jab_cancel_delay_s,
            Move::Cross => self.cross_cancel_delay_s,
            Move::LeadHook => self.lead_hook_cancel_delay_s,
            Move::RearHook => self.rear_hook_cancel_delay_s,
            Move::LeadUppercut => self.lead_uppercut_cancel_delay_s,
            Move::RearUppercut => self.rear_uppercut_cancel_delay_s,
        };
        if delay_s.is_finite() { delay_s.max(0.0) } else { 0.0 }
    }

    /// How near its guard `punch_move` starts with `guard_first`, rad (`Recovery::ready_to_punch` takes care of a
    /// value that is not a number).
    pub fn guard_tolerance_rad_of(&self, punch_move: Move) -> f32 {
        match punch_move {
            Move::Jab => self.jab_guard_tolerance_rad,
            Move::Cross => self.cross_guard_tolerance_rad,
            Move::LeadHook => self.lead_hook_guard_tolerance_rad,
            Move::RearHook => self.rear_hook_guard_tolerance_rad,
            Move::LeadUppercut => self.lead_uppercut_guard_tolerance_rad,
            Move::RearUppercut => self.rear_uppercut_guard_tolerance_rad,
        }
    }
}
