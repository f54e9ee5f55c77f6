//! `PunchTrainingServer`: the headless training world. It serves the trainer over TCP on loopback and runs
//! N characters, each with its own bag, in lockstep with Godot's physics.
//!
//! Isolation and determinism: slots live in "arenas" (SubViewports with their own physics world) of up to
//! 32; every slot sits at the arena's origin and is kept apart from the others by collision layers, so each
//! slot computes with exactly the same coordinates. A reset replaces the arenas with fresh worlds, so every
//! episode starts from the same engine state (no warm-start history, same body order).
//!
//! Lockstep: while waiting for a command the server blocks inside `physics_process`, so no physics step
//! happens between commands; a command that needs frames returns and lets Godot step.

use std::io::ErrorKind;
use std::net::{TcpListener, TcpStream};
use std::os::fd::AsRawFd;
use std::time::{Duration, Instant};

use glam::Vec3;
use godot::classes::{CylinderShape3D, Engine, INode, Node, Node3D, Os, PackedScene, PhysicsServer3D, RigidBody3D, SubViewport};
use godot::classes::sub_viewport::UpdateMode;
use godot::global::{godot_error, godot_print};
use godot::obj::{Base, Gd, NewAlloc, NewGd, Singleton, WithBaseField};
use godot::prelude::{GodotClass, godot_api};
use punch_core::character::PHYSICS_HZ;
use punch_core::protocol::{Message, ProtocolError, error_reply};
use punch_core::sensing::{CharacterGeometry, FrameReading};
use punch_core::session::{BagPlacement, Outcome, Session, World};

use crate::convert::{body_state, vec3};
use crate::punch_character::{PunchCharacter, Rig, configure_joints};

/// Slots per arena: collision layers are 32 bits, one per slot.
const SLOTS_PER_ARENA: usize = 32;

/// The headless training server the Python trainer starts and drives (see docs/protocol.md). Command-line
/// arguments after `--` override the exported values: `--port=`, `--slots=`, `--decision-period=`,
/// `--idle-timeout-s=`.
#[derive(GodotClass)]
#[class(base = Node, init)]
pub struct PunchTrainingServer {
    /// TCP port on 127.0.0.1; 0 picks a free port (printed in the ready line).
    #[export]
    port: i32,
    /// Number of characters simulated side by side (N).
    #[export]
    #[init(val = 1)]
    slot_count: i32,
    /// Physics frames each action is held for.
    #[export]
    #[init(val = 5)]
    decision_period: i32,
    /// Seconds without a client (or without a message from it) after which the server quits.
    #[export]
    #[init(val = 120.0)]
    idle_timeout_s: f32,
    /// The character scene (the addon's punch_character.tscn).
    #[export]
    character_scene: Option<Gd<PackedScene>>,
    /// The sandbag scene (the addon's punch_sandbag.tscn).
    #[export]
    sandbag_scene: Option<Gd<PackedScene>>,

    listener: Option<TcpListener>,
    connections: Vec<TcpStream>,
    session: Option<Session>,
    world: Option<ArenaWorld>,
    /// The client whose command is running, if one is.
    running: Option<usize>,
    base: Base<Node>,
}

#[godot_api]
impl INode for PunchTrainingServer {
    fn ready(&mut self) {
        if let Err(error) = self.start() {
            godot_error!("PunchTrainingServer: {error}");
            self.quit(1);
        }
    }

    fn physics_process(&mut self, _delta: f64) {
        if self.world.is_none() {
            return;
        }
        if let Some(client) = self.running {
            let (Some(session), Some(world)) = (self.session.as_mut(), self.world.as_mut()) else { return };
            match session.physics_frame(world) {
                Some(reply) => {
                    self.running = None;
                    self.send(client, &reply);
                }
                None => return,
            }
        }
        self.serve();
    }
}

impl PunchTrainingServer {
    fn start(&mut self) -> Result<(), String> {
        for argument in Os::singleton().get_cmdline_user_args().as_slice() {
            let argument = argument.to_string();
            let Some((key, value)) = argument.trim_start_matches("--").split_once('=') else { continue };
            let number = || value.parse::<f64>().map_err(|_| format!("--{key}={value}: not a number"));
            match key {
                "port" => self.port = number()? as i32,
                "slots" => self.slot_count = number()? as i32,
                "decision-period" => self.decision_period = number()? as i32,
                "idle-timeout-s" => self.idle_timeout_s = number()? as f32,
                _ => {}
            }
        }
        let ticks = Engine::singleton().get_physics_ticks_per_second();
        if ticks != PHYSICS_HZ as i32 {
            return Err(format!("physics runs at {ticks} Hz; the punch spec needs {PHYSICS_HZ} Hz"));
        }
        if !(1..=4096).contains(&self.slot_count) || !(1..=60).contains(&self.decision_period) || !(0..=65535).contains(&self.port) {
            return Err(format!("bad settings: slots {} (1..=4096), decision period {} (1..=60), port {}", self.slot_count, self.decision_period, self.port));
        }
        let character_scene = self.character_scene.clone().ok_or("no character_scene set")?;
        let sandbag_scene = self.sandbag_scene.clone().ok_or("no sandbag_scene set")?;
        let listener = TcpListener::bind(("127.0.0.1", self.port as u16)).map_err(|e| format!("cannot listen on port {}: {e}", self.port))?;
        let port = listener.local_addr().map_err(|e| e.to_string())?.port();
        listener.set_nonblocking(true).map_err(|e| e.to_string())?;
        self.listener = Some(listener);
        let mut world = ArenaWorld {
            parent: self.base().clone(),
            arenas: Vec::new(),
            slots: Vec::new(),
            slot_count: self.slot_count as usize,
            character_scene: headless_template(&character_scene)?,
            sandbag_scene: headless_template(&sandbag_scene)?,
        };
        world.reset(&vec![BagPlacement::default(); self.slot_count as usize])?;
        self.world = Some(world);
        self.session = Some(Session::new(self.decision_period as usize));
        godot_print!("PUNCH_SERVER_READY port={port} slots={} decision_period={}", self.slot_count, self.decision_period);
        Ok(())
    }

    /// Answers messages from every client until one starts a physics run, or quits when idle too long.
    fn serve(&mut self) {
        let mut last_activity = Instant::now();
        loop {
            self.accept_pending();
            let Some(index) = self.wait_readable() else {
                if last_activity.elapsed().as_secs_f32() > self.idle_timeout_s {
                    godot_print!("PunchTrainingServer: no request for {} s, quitting", self.idle_timeout_s);
                    self.quit(0);
                    return;
                }
                continue;
            };
            last_activity = Instant::now();
            let message = match Message::read_from(&mut self.connections[index]) {
                Ok(message) => message,
                Err(ProtocolError::Content(reason)) => {
                    self.send(index, &error_reply(&reason));
                    continue;
                }
                Err(ProtocolError::Framing(reason)) => {
                    // This stream cannot be resynchronised: say why and drop this client only.
                    self.send(index, &error_reply(&format!("{reason}; closing the connection")));
                    self.connections.remove(index);
                    continue;
                }
                Err(ProtocolError::Closed | ProtocolError::Io(_)) => {
                    self.connections.remove(index);
                    continue;
                }
            };
            let (Some(session), Some(world)) = (self.session.as_mut(), self.world.as_mut()) else { return };
            match session.handle(&message, world) {
                Outcome::Reply(reply) => self.send(index, &reply),
                Outcome::Running => {
                    self.running = Some(index);
                    return;
                }
                Outcome::Close(reply) => {
                    self.send(index, &reply);
                    self.connections.remove(index);
                }
            }
        }
    }

    /// Takes every client waiting in the listen queue.
    fn accept_pending(&mut self) {
        let Some(listener) = &self.listener else { return };
        loop {
            match listener.accept() {
                Ok((stream, _)) => {
                    let timeout = Some(Duration::from_secs_f32(self.idle_timeout_s.max(0.1)));
                    if stream.set_nonblocking(false).is_ok() && stream.set_nodelay(true).is_ok() && stream.set_read_timeout(timeout).is_ok() {
                        self.connections.push(stream);
                    }
                }
                Err(error) if error.kind() == ErrorKind::WouldBlock => return,
                Err(error) => {
                    godot_error!("PunchTrainingServer: accept failed: {error}");
                    return;
                }
            }
        }
    }

    /// Index of a client with bytes to read, waiting up to 20 ms (the listener is polled too, so a new
    /// client is taken on the next round).
    fn wait_readable(&self) -> Option<usize> {
        let mut fds: Vec<libc::pollfd> = self
            .connections
            .iter()
            .map(|c| libc::pollfd { fd: c.as_raw_fd(), events: libc::POLLIN, revents: 0 })
            .collect();
        if let Some(listener) = &self.listener {
            fds.push(libc::pollfd { fd: listener.as_raw_fd(), events: libc::POLLIN, revents: 0 });
        }
        // SAFETY: `fds` is a valid array of pollfd for the duration of the call.
        let ready = unsafe { libc::poll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, 20) };
        if ready <= 0 {
            return None;
        }
        fds[..self.connections.len()].iter().position(|fd| fd.revents & (libc::POLLIN | libc::POLLHUP | libc::POLLERR) != 0)
    }

    fn send(&mut self, index: usize, message: &Message) {
        let Some(connection) = self.connections.get_mut(index) else { return };
        if message.write_to(connection).is_err() {
            self.connections.remove(index);
        }
    }

    fn quit(&mut self, code: i32) {
        self.world = None;
        self.base().get_tree().quit_ex().exit_code(code).done();
    }
}

struct SlotNodes {
    character: Gd<PunchCharacter>,
    bag: Gd<RigidBody3D>,
    geometry: CharacterGeometry,
}

/// The `World` the session drives: arenas of slots made from the addon's scenes.
struct ArenaWorld {
    parent: Gd<Node>,
    arenas: Vec<Gd<SubViewport>>,
    slots: Vec<SlotNodes>,
    slot_count: usize,
    character_scene: Gd<PackedScene>,
    sandbag_scene: Gd<PackedScene>,
}

impl ArenaWorld {
    fn build_slot(&self, arena: &mut Gd<SubViewport>, slot: usize, placement: &BagPlacement) -> Result<SlotNodes, String> {
        let layer = 1u32 << (slot % SLOTS_PER_ARENA);
        let character = self
            .character_scene
            .instantiate()
            .and_then(|node| node.try_cast::<PunchCharacter>().ok())
            .ok_or("the character scene's root is not a PunchCharacter")?;
        for child in character.get_children().iter_shared() {
            if let Ok(mut body) = child.try_cast::<godot::classes::CollisionObject3D>() {
                // Two-sided masks: under Jolt a body that does not mask the other acts as immovable to it.
                body.set_collision_layer(layer);
                body.set_collision_mask(layer);
            }
        }
        let mut sandbag = self.sandbag_scene.instantiate().and_then(|n| n.try_cast::<Node3D>().ok()).ok_or("the sandbag scene's root is not a Node3D")?;
        sandbag.set_position(godot::builtin::Vector3::new(placement.side_m, placement.height_m, placement.distance_m));
        let mut bag = sandbag.get_node_or_null("Bag").and_then(|n| n.try_cast::<RigidBody3D>().ok()).ok_or("the sandbag scene has no RigidBody3D 'Bag'")?;
        bag.set_collision_layer(layer);
        bag.set_collision_mask(layer);
        arena.add_child(&character);
        arena.add_child(&sandbag);

        let (bag_radius_m, bag_height_m) = bag_size(&bag).ok_or("the bag's first shape is not a CylinderShape3D")?;
        let mut geometry = character.bind().rig().map(|rig| rig.geometry).ok_or("the character is not ready (see the error above)")?;
        geometry.bag_radius_m = bag_radius_m;
        geometry.bag_height_m = bag_height_m;
        geometry.bag_mass_kg = bag.get_mass();
        Ok(SlotNodes { character, bag, geometry })
    }
}

impl World for ArenaWorld {
    fn slot_count(&self) -> usize {
        self.slot_count
    }

    fn reset(&mut self, placements: &[BagPlacement]) -> Result<(), String> {
        for mut arena in self.arenas.drain(..) {
            self.parent.remove_child(&arena);
            arena.queue_free();
        }
        self.slots.clear();
        for first in (0..self.slot_count).step_by(SLOTS_PER_ARENA) {
            let mut arena = SubViewport::new_alloc();
            arena.set_use_own_world_3d(true);
            arena.set_update_mode(UpdateMode::DISABLED);
            self.parent.add_child(&arena);
            for slot in first..(first + SLOTS_PER_ARENA).min(self.slot_count) {
                let nodes = self.build_slot(&mut arena, slot, &placements[slot])?;
                self.slots.push(nodes);
            }
            self.arenas.push(arena);
        }
        Ok(())
    }

    fn geometry(&self, slot: usize) -> CharacterGeometry {
        self.slots[slot].geometry
    }

    fn read(&self, slot: usize) -> FrameReading {
        let nodes = &self.slots[slot];
        let character = nodes.character.bind();
        let Some(rig) = character.rig() else { return FrameReading::default() };
        let (fist_impulses, character_impulse) = bag_contacts(&nodes.bag, rig);
        FrameReading { bodies: rig.read_bodies(), bag: body_state(&nodes.bag), fist_impulses, character_impulse }
    }

    fn drive(&mut self, slot: usize, motor_velocities: &[Vec3; 5]) {
        let mut character = self.slots[slot].character.bind_mut();
        if let Some(rig) = character.rig_mut() {
            rig.drive(motor_velocities);
        }
    }
}

/// Impulses applied to the bag in the last step, from the bag's reported contacts: by each fist, and by
/// the whole character.
fn bag_contacts(bag: &Gd<RigidBody3D>, rig: &Rig) -> ([Vec3; 2], Vec3) {
    let mut fists = [Vec3::ZERO; 2];
    let mut character = Vec3::ZERO;
    let Some(state) = PhysicsServer3D::singleton().body_get_direct_state(bag.get_rid()) else { return (fists, character) };
    for contact in 0..state.get_contact_count() {
        let collider = state.get_contact_collider_id(contact);
        if !rig.body_ids.contains(&collider) {
            continue;
        }
        let impulse = vec3(state.get_contact_impulse(contact));
        character += impulse;
        let shape = state.get_contact_collider_shape(contact);
        for side in 0..2 {
            if collider == rig.forearm_ids[side] && shape == rig.fist_shape_indices[side] {
                fists[side] += impulse;
            }
        }
    }
    (fists, character)
}

/// The scene without its meshes, packed once: the headless server never draws, resets instance it for
/// every slot, and every moving body would otherwise push transform updates to its meshes each frame.
fn headless_template(scene: &Gd<PackedScene>) -> Result<Gd<PackedScene>, String> {
    let mut root = scene.instantiate().ok_or("a scene could not be instantiated")?;
    strip_visuals(&mut root);
    configure_joints(&root);
    let mut template = PackedScene::new_gd();
    let packed = template.pack(&root);
    root.free();
    if packed != godot::global::Error::OK {
        return Err(format!("could not pack a headless copy of a scene: {packed:?}"));
    }
    Ok(template)
}

/// Frees the meshes under `node`: the headless server never draws, and every moving body would otherwise
/// push transform updates to its meshes each frame.
fn strip_visuals(node: &mut Gd<Node>) {
    for mut child in node.get_children().iter_shared() {
        if child.is_class("VisualInstance3D") {
            node.remove_child(&child);
            child.free();
        } else {
            strip_visuals(&mut child);
        }
    }
}

fn bag_size(bag: &Gd<RigidBody3D>) -> Option<(f32, f32)> {
    let owner = *bag.get_shape_owners().as_slice().first()? as u32;
    let cylinder = bag.shape_owner_get_shape(owner, 0)?.try_cast::<CylinderShape3D>().ok()?;
    Some((cylinder.get_radius(), cylinder.get_height()))
}
