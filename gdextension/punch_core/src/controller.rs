//! One character's controller: holds the current joint targets, turns engine readings into features, and
//! computes the joint motor commands. The training server and `PunchController` both run this.

use glam::Vec3;

use crate::character::{DOF_COUNT, JOINTS, joint_target, motor_velocities, targets_from_action};
use crate::error::{CoreError, CoreResult};
use crate::sensing::{CharacterGeometry, FEATURE_COUNT, FrameReading, Sensor};

#[derive(Debug, Clone)]
pub struct CharacterController {
    sensor: Sensor,
    targets: [f32; DOF_COUNT],
}

impl CharacterController {
    pub fn new(geometry: CharacterGeometry) -> Self {
        Self {
            sensor: Sensor::new(geometry),
            targets: [0.0; DOF_COUNT],
        }
    }

    /// Back to the guard pose targets, with no frame history.
    pub fn reset(&mut self) {
        self.sensor.reset();
        self.targets = [0.0; DOF_COUNT];
    }

    /// Takes a new action in [-1, 1]^10 (values outside are clamped; wrong length or NaN is an error).
    pub fn set_action(&mut self, action: &[f32]) -> CoreResult<()> {
        self.targets = targets_from_action(action).ok_or_else(|| {
            CoreError::BadInput(format!(
                "an action is {DOF_COUNT} finite values, got {action:?}"
            ))
        })?;
        Ok(())
    }

    pub fn targets(&self) -> &[f32; DOF_COUNT] {
        &self.targets
    }

    /// Motor target velocities for each joint (`JOINTS` order), in Godot's 6DOF motor convention.
    pub fn motor_commands(&self, reading: &FrameReading) -> [Vec3; 5] {
        let rotations = self.sensor.joint_rotations(reading);
        std::array::from_fn(|joint| {
            motor_velocities(rotations[joint], joint_target(joint, &self.targets))
        })
    }

    /// Features of the frame just simulated.
    pub fn features(&mut self, reading: &FrameReading) -> [f32; FEATURE_COUNT] {
        self.sensor.features(reading)
    }

    pub fn geometry(&self) -> &CharacterGeometry {
        self.sensor.geometry()
    }
}

/// Number of joints, re-exported for array sizes in the engine layer.
pub const JOINT_COUNT: usize = JOINTS.len();
