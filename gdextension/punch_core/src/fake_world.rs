//! A fake physics world for unit tests: each slot's character slides its whole body toward the bag at a
//! speed set by how hard its harder-driven elbow motor is driven, and stops against the bag with that fist's
//! contact. Crude, but it moves a fist, touches a bag and answers every `World` call, without Godot.

use glam::{Quat, Vec3};

use crate::contract::character::{BODY_COUNT, Body};
use crate::contract::motion::RootPose;
use crate::contract::sensing::{BagContact, CharacterGeometry, FrameReading};
use crate::contract::spec::EpisodeConditions;
use crate::game::punch::Touch;
use crate::training::session::World;

const FIST_OFFSET: Vec3 = Vec3::new(0.0, -0.155, 0.0);
const START: Vec3 = Vec3::new(0.0, 1.505, 0.2);
const DT: f32 = 1.0 / 120.0;
/// The engine id `touches_slot` gives the bag.
pub const FAKE_BAG_ID: u64 = 77;

/// A character at the origin facing +Z, every body at rest in the guard pose.
pub fn rest_geometry() -> CharacterGeometry {
    CharacterGeometry {
        rest_rotations: [Quat::IDENTITY; BODY_COUNT],
        fist_offsets: [FIST_OFFSET; 2],
        fist_radius_m: 0.045,
        joint_anchors: [(Vec3::ZERO, Vec3::ZERO); 5],
        bag_radius_m: 0.175,
        bag_height_m: 1.0,
        bag_mass_kg: 35.0,
        root_rotation: Quat::IDENTITY,
        root_position: Vec3::ZERO,
        pelvis_rest_position: Vec3::ZERO,
    }
}

/// The fake world's character: every body starts at `START`, the pelvis too (the whole character slides, its
/// root with it, so its features show the bag coming nearer).
fn fake_geometry() -> CharacterGeometry {
    CharacterGeometry { pelvis_rest_position: START, ..rest_geometry() }
}

pub struct FakeWorld {
    readings: Vec<FrameReading>,
    commands: Vec<[Vec3; 5]>,
    /// Every drive call: (slot, commands), for tests that check what was driven.
    pub driven: Vec<(usize, [Vec3; 5])>,
    pub resets: usize,
    /// Every `move_pelvis` call: (slot, root pose).
    pub pelvis_moves: Vec<(usize, RootPose)>,
    /// Every `carry_bodies` call: (slot, root pose).
    pub carried: Vec<(usize, RootPose)>,
    /// Every `move_rope` call: (slot, how far the carry moved the rope's top (its translation)).
    pub ropes: Vec<(usize, Vec3)>,
}

impl FakeWorld {
    pub fn new(slots: usize) -> Self {
        let mut world = Self {
            readings: Vec::new(),
            commands: Vec::new(),
            driven: Vec::new(),
            resets: 0,
            pelvis_moves: Vec::new(),
            carried: Vec::new(),
            ropes: Vec::new(),
        };
        world.place(&vec![EpisodeConditions::DEFAULT; slots]);
        world
    }

    fn place(&mut self, placements: &[EpisodeConditions]) {
        self.readings = placements
            .iter()
            .map(|placement| {
                let mut reading = FrameReading::default();
                for body in &mut reading.bodies {
                    *body = crate::contract::sensing::BodyState {
                        position: START,
                        rotation: Quat::IDENTITY,
                        ..Default::default()
                    };
                }
                reading.bag.rotation = Quat::IDENTITY;
                reading.bag.position = placement.position();
                reading
            })
            .collect();
        self.commands = vec![[Vec3::ZERO; 5]; placements.len()];
    }

    pub fn read_slot(&self, slot: usize) -> FrameReading {
        self.readings[slot]
    }

    /// The slot's bag contacts as touches of the bag (collider id `FAKE_BAG_ID`), as a game reports them.
    pub fn touches_slot(&self, slot: usize) -> Vec<Touch> {
        let reading = &self.readings[slot];
        reading.contacts[..reading.contact_count]
            .iter()
            .map(|c| Touch { body: c.body, collider: FAKE_BAG_ID, point: c.point, impulse: c.impulse, overlap: false })
            .collect()
    }

    pub fn drive_slot(&mut self, slot: usize, commands: &[Vec3; 5]) {
        self.commands[slot] = *commands;
        self.driven.push((slot, *commands));
    }

    /// One physics step of every slot.
    pub fn step(&mut self) {
        let geometry = rest_geometry();
        for (reading, commands) in self.readings.iter_mut().zip(&self.commands) {
            // The elbow driven harder punches (the right on a tie), so a mirrored punch lands with the left fist.
            let (elbow, punching) = if commands[4].length() > commands[2].length() {
                (commands[4], Body::ForearmL)
            } else {
                (commands[2], Body::ForearmR)
            };
            let forearm = reading.bodies[punching.index()];
            let reach_z = reading.bag.position.z - geometry.bag_radius_m - geometry.fist_radius_m;
            let speed = (0.3 * elbow.length()).min(6.0);
            let z = (forearm.position.z + speed * DT).min(reach_z);
            let velocity = Vec3::new(0.0, 0.0, (z - forearm.position.z) / DT);
            for body in &mut reading.bodies {
                body.position.z = z;
                body.linear_velocity = velocity;
            }
            let fist = reading.bodies[punching.index()].position + FIST_OFFSET;
            reading.contact_count = 0;
            if z >= reach_z {
                reading.contacts[0] =
                    BagContact { body: punching.index(), point: fist + Vec3::Z * 0.045, impulse: Vec3::Z };
                reading.contact_count = 1;
            }
        }
    }
}

impl World for FakeWorld {
    fn slot_count(&self) -> usize {
        self.readings.len()
    }

    fn reset(&mut self, placements: &[EpisodeConditions]) -> Result<(), String> {
        self.resets += 1;
        self.place(placements);
        Ok(())
    }

    fn place_bag(&mut self, slot: usize, placement: &EpisodeConditions) {
        self.readings[slot].bag.position = placement.position();
    }

    fn geometry(&self, _slot: usize) -> CharacterGeometry {
        fake_geometry()
    }

    fn read(&self, slot: usize) -> FrameReading {
        self.read_slot(slot)
    }

    fn drive(&mut self, slot: usize, motor_velocities: &[Vec3; 5]) {
        self.drive_slot(slot, motor_velocities);
    }

    fn move_pelvis(&mut self, slot: usize, root: &RootPose) {
        self.pelvis_moves.push((slot, *root));
    }

    fn carry_bodies(&mut self, slot: usize, root: &RootPose, _with_bag: bool) {
        self.carried.push((slot, *root));
    }

    fn move_rope(&mut self, slot: usize, carry: &RootPose) {
        self.ropes.push((slot, carry.position));
    }
}
