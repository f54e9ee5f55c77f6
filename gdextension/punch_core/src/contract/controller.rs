//! One character's controller: smooths the agent's actions, holds the joint targets, turns engine readings
//! into features, and computes the joint motor commands. The training server and `PunchController` both run
//! this.

use glam::Vec3;

use crate::contract::character::{DOF_COUNT, joint_target, motor_velocities, targets_from_action};
use crate::contract::sensing::{CharacterGeometry, FEATURE_COUNT, FrameReading, Sensor};
use crate::contract::smoothing::Smoother;
use crate::error::{CoreError, CoreResult};

#[derive(Debug, Clone)]
pub struct CharacterController {
    sensor: Sensor,
    smoother: Smoother,
    targets: [f32; DOF_COUNT],
}

impl CharacterController {
    /// A controller whose actions are smoothed over the last `smoothing_window` actions (1: off).
    pub fn new(geometry: CharacterGeometry, smoothing_window: usize) -> Self {
        Self { sensor: Sensor::new(geometry), smoother: Smoother::new(smoothing_window), targets: [0.0; DOF_COUNT] }
    }

    /// Back to the guard pose targets, with no frame or action history.
    pub fn reset(&mut self) {
        self.sensor.reset();
        self.smoother.reset();
        self.targets = [0.0; DOF_COUNT];
    }

    /// Takes a raw action in [-1, 1]^10 (values outside are clamped; a wrong length or NaN is an error),
    /// smooths it, and returns the action actually executed.
    pub fn set_action(&mut self, action: &[f32]) -> CoreResult<[f32; DOF_COUNT]> {
        let bad = || CoreError::BadInput(format!("an action is {DOF_COUNT} finite values, got {action:?}"));
        let raw: [f32; DOF_COUNT] = action.try_into().map_err(|_| bad())?;
        if raw.iter().any(|v| !v.is_finite()) {
            return Err(bad());
        }
        let executed = self.smoother.push(&raw.map(|v| v.clamp(-1.0, 1.0)));
        self.targets = targets_from_action(&executed).ok_or_else(bad)?;
        Ok(executed)
    }

    /// Holds these joint targets (rad, action order) until the next action: a pose to drive to, as a recovery
    /// does to a stance's guard.
    pub fn set_targets(&mut self, targets: [f32; DOF_COUNT]) {
        self.targets = targets;
    }

    /// Motor target velocities for each joint (`JOINTS` order), in Godot's 6DOF motor convention.
    pub fn motor_commands(&self, reading: &FrameReading) -> [Vec3; 5] {
        let rotations = self.sensor.joint_rotations(reading);
        std::array::from_fn(|joint| motor_velocities(rotations[joint], joint_target(joint, &self.targets)))
    }

    pub fn geometry(&self) -> &CharacterGeometry {
        self.sensor.geometry()
    }

    /// World positions and velocities of the fists: [(position, velocity); right, left].
    pub fn fists(&self, reading: &FrameReading) -> [(Vec3, Vec3); 2] {
        self.sensor.fists(reading)
    }

    /// Features of the frame just simulated.
    pub fn features(&mut self, reading: &FrameReading) -> [f32; FEATURE_COUNT] {
        self.sensor.features(reading)
    }
}
