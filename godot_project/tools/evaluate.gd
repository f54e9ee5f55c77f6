## The evaluator's one driver: plays a list of episodes through PunchController itself, each in its own conditions
## (where the target is and how it moves, how the character's body moves, its arms' size, the noise), and writes
## what every punch did. For `punch eval` (its scenarios: trainer/punch_trainer/pipelines/evaluation.py,
## docs/evaluation.md), `punch replay` and `punch bench inference`.
##
## tools/godot --headless --fixed-fps 120 --path godot_project --script res://tools/evaluate.gd -- \
##     --policy=PATH --episodes=FILE.json --out=DIR [--record=0|1] [--characters=64]
##     [--characters-per-world=16] [--idle-frames=0]
##
## `--episodes` names a JSON list; each episode is an object (every key optional but `seed`):
## - `placement`: the target's centre in the character's frame (`distance_m`, `height_m`, `side_m`) and the
##   bag's swing at the start (`velocity_side_mps`, `velocity_forward_mps`); default: the spec's default target;
## - `sigma`, `noise_decisions` (-1: every decision), `seed` (the controller's noise seed);
## - `start`: "guard", or "after_punch": the controller punches once, then again at once from where that left
##   it, the bag put back as placed (only the second punch is recorded and counted);
## - `arms`: [upper arm, forearm] scales, sized through `PunchCharacter.size_arms` right after the character
##   enters the tree (a size it refuses ends the run with exit code 2);
## - `lead_s`: how long the episode runs before its punch (a moving body moves from the start, a moving
##   target's hook from the punch on);
## - `body`: a motion (below) of the character's holder, the node a game moves (its CharacterBody3D), with the
##   sandbag riding along: its hook pinned to a kinematic body that is the holder's child (a joint does not
##   follow its node), the bag `top_level`, hanging from the carried hook under physics at the holder's velocity;
## - `target`: a motion of the sandbag's hook alone (the character stands): a kinematic body that moves itself
##   every physics frame (`sync_to_physics`), the bag starting at the hook's velocity;
## - `move`: the move thrown (`punch(move)`, the policy as the moveset's for it, in the episode's `stance`; a
##   left-hand move at the mirror image of the placement), `stance`, `stance_pose`;
## - `combo`: a list of moves thrown as one `combo()` with the addon's moveset (every move's shipped policy; the
##   placement as given, for both hands; with `stance_pose`, the stance's moveset, as docs/moves.md tells a game),
##   the episode ending at `combo_finished`;
## - `until_recovered`: the character returns to guard after its (last) punch (`auto_recover`), and the episode
##   ends at the first `recovered` after its `combo_finished`;
## - `guard_first` (default true): `PunchController.guard_first`; false: a punch asked for away from the guard
##   starts from wherever the arms are;
## - `struck`: {`part`, `impulse_ns`, `direction` [x, y, z] in the character's frame}: no punch; the character in
##   guard (standing, or on the episode's `body` motion) is struck by the game (`PunchCharacter.take_hit`: the torso
##   15 cm above its centre, the head at its centre, an arm at its upper arm) after `lead_s` (at least 2 frames), and
##   the episode ends at `recovered` (after `knocked_down`, `recover()` is called 1 s on);
## - `reset_target`: each later punch of a combo starts with the bag hanging as placed again (its start, not where
##   the punches before swung it);
## - `defender`: {`blocks`, `part`, `head_up_m`, `turned_deg`, `motion`}: a second character of the addon's scene stands
##   facing the first (turned `turned_deg` to its left from there) instead of the bag, its root at the placement's
##   distance and side (the height is its own; with a `motion`, below, in a holder of its own that moves it in its own
##   frame from the episode's start, or the punch's with no lead), and the punch aims at its `part`:
##   "head" (the `Head` body, on its neck; `head_up_m` higher up it, as an own rig's, with `size_head`) or "torso";
##   with `blocks`, its own controller calls `block()` as the episode starts (`lead_s` later comes the punch: the warning). The row's struck entry is then {`outcome`,
##   `head_impulse_ns`}: the punch's `punch_finished` outcome ("landed": on the head or the body, "blocked": on an
##   arm first, "whiffed") and the impulse of the fist's first frame on the part aimed at (N s; absent when it never
##   reached it);
## - `cancel_delay_s`: a combo's moveset with this cancel delay for every move (the next punch starts that long
##   after the one before landed, or ended without landing).
## A motion (the moving node's own frame at the start: +Z ahead, +X its left, +Y up): `velocity_mps` [left, up,
## forward] (turning while walking walks an arc), `turn_dps` (about +Y, positive to the left), `lunge_m` over
## `lunge_s` (forward, minimum-jerk, begins with the punch), `bob_m` at `bob_hz` (vertical, a sine). An empty
## motion ({}) still carries the hook as described, without moving.
##
## Episodes run side by side, `--characters` at a time, in episode order: each batch is built fresh, a
## SubViewport with its own World3D per `--characters-per-world` pairs, two collision layers per pair
## (tools/punch_pair.gd), so every punch starts from the same state whatever its batch.
##
## Output in DIR: `episodes.json` with one row per episode, in order: [hits on the target (the controller's
## `hit` signal with the target's Bag as the body; a combo's: its punches that struck it), target_out_of_reach
## signals, how far outside the reach volume the target was at the last of them (m), how the (last) punch ended,
## how far the moved node went (m, straight line), upper arm, forearm, shoulder width (m, as `arm_lengths()`
## reports them), timings: per punch [its `punch_started`, its first hit on the target (-1: none)] in physics
## frames from the command, and with `until_recovered` the frame of `recovered` as a last entry], and a struck
## character's figures ({} for a punch): `peak_deg`, the largest turn of any body from its guard (degrees, in the
## character's frame), `head_moved_m`, the head's largest move (m), `back_s` and `recovered_s`, when every body was back
## within 10 degrees of its guard and when `recovered` came (s after the hit; -1: never; `back_s` 0 if none left),
## `staggered` and `knocked_down`; `arm_scale_range`; the
## feature names, frames and decisions of a punch; the controllers' inference counts and their work per
## physics frame per batch (and, with `--idle-frames=N`, per idle frame: each batch's characters stand N frames
## after their punches, for `punch bench inference`). With `--record=1` also features.f32 [episodes, frames, F],
## observations.f32 [episodes, decisions, obs], mean_actions.f32 and actions.f32 [episodes, decisions, 10]
## (little-endian float32, in episode order). Progress lines: `EVALUATE_PROGRESS done total`.
extends SceneTree

const PunchPair := preload("res://tools/punch_pair.gd")
## The moveset a combo plays: the addon's, or from the stance's guard (`stance_pose`) the stance's.
const ADDON_MOVESET := "res://addons/punch_controller/policies/boxing.tres"
const STANCE_MOVESET := "res://addons/punch_controller/policies/boxing_stance.tres"
const MOVES: Array[StringName] = [&"jab", &"cross", &"lead_hook", &"rear_hook", &"lead_uppercut", &"rear_uppercut"]
## Seconds after a hit a struck character is watched at most.
const STRUCK_WATCH_S := 4.0
## A struck character's bodies, and how near its guard each must be to be back (degrees).
const STRUCK_BODIES := ["Torso", "UpperArmR", "ForearmR", "UpperArmL", "ForearmL", "Head"]
const BACK_IN_GUARD_DEG := 10.0


## The node a game moves: the character's holder (`body`) or the target's hook (`target`) run the same motion.
class Motion:
	var spec: Dictionary
	var time_s := 0.0
	var base_y := 0.0
	## When the lunge starts (the punch's start), s after the motion's.
	var lunge_start_s := 0.0

	func _init(motion: Dictionary) -> void:
		spec = motion

	func advance(node: Node3D, delta: float) -> void:
		if time_s == 0.0:
			base_y = node.position.y
		var before := time_s
		time_s += delta
		node.rotate_y(deg_to_rad(float(spec.get("turn_dps", 0.0))) * delta)
		var velocity: Array = spec.get("velocity_mps", [0.0, 0.0, 0.0])
		node.position += node.basis * Vector3(velocity[0], velocity[1], velocity[2]) * delta
		var lunge_m := float(spec.get("lunge_m", 0.0))
		if lunge_m > 0.0:
			var lunge_s := float(spec.get("lunge_s", 0.25))
			var step := lunge_m * (_minimum_jerk((time_s - lunge_start_s) / lunge_s)
				- _minimum_jerk((before - lunge_start_s) / lunge_s))
			node.position += node.basis * Vector3(0.0, 0.0, step)
		var bob_m := float(spec.get("bob_m", 0.0))
		if bob_m > 0.0:
			node.position.y = base_y + bob_m * sin(TAU * float(spec.get("bob_hz", 2.0)) * time_s)

	## The velocity (global) the motion starts with, for a bag that hangs from a moving hook.
	func start_velocity(node: Node3D) -> Vector3:
		var velocity: Array = spec.get("velocity_mps", [0.0, 0.0, 0.0])
		return node.global_basis * Vector3(velocity[0], velocity[1], velocity[2])

	static func _minimum_jerk(fraction: float) -> float:
		var t := clampf(fraction, 0.0, 1.0)
		return t * t * t * (10.0 - 15.0 * t + 6.0 * t * t)


## The character's holder (a game's CharacterBody3D): moves while `motion` is set.
class Holder extends Node3D:
	var motion: Motion

	func _physics_process(delta: float) -> void:
		if motion != null:
			motion.advance(self, delta)


## The sandbag's hook of a moving target: a kinematic body that moves itself while `motion` is set.
class MovingHook extends AnimatableBody3D:
	var motion: Motion

	func _physics_process(delta: float) -> void:
		if motion != null:
			motion.advance(self, delta)


## One episode of the batch under way.
class Slot:
	var controller: Node
	var row: Array
	## The node that moves, its Motion and the bag that starts at its velocity (or null: nothing moves).
	var moved: Node3D
	var motion: Motion
	## Where the moving node stood at the start (its straight-line distance from there is the row's "moved").
	var moved_from := Vector3.ZERO
	var bag: RigidBody3D
	## The motion starts with the punch (a moving target, or no lead), not with the episode.
	var motion_with_punch := false
	## Physics frames left before the punch (-1: punched).
	var lead_frames := 0
	## The move it throws (empty: the policy, with the right hand).
	var move := &""
	## The moves of a combo it throws instead (empty: one punch).
	var combo: Array = []
	## The physics frame (`_frame`) of its command.
	var commanded_at := 0
	## A hit instead of a punch (`struck`), its bodies' guard rotations and head's place when it came, and the figures.
	var struck := {}
	var character: Node3D
	var guard_rotations := {}
	var head_at := Vector3.ZERO
	var back_at := -1
	## Measured until `recovered` has come and every body is back in guard (the head swings on its neck after the
	## driven joints are back), or `STRUCK_WATCH_S` after the hit.
	var struck_open := true


const KINDS := ["features", "observations", "mean_actions", "actions"]

var _options := {
	"policy": "", "episodes": "", "out": "", "record": "0", "characters": "64", "characters-per-world": "16",
	"idle-frames": "0",
}
var _episodes: Array = []
var _rows: Array = []
var _next := 0
var _slots: Array[Slot] = []
var _arenas: Array[SubViewport] = []
var _pending := 0
var _failed := false
var _record := false
var _files := {}
var _meta := {}
var _inference := {"calls": 0, "rows": 0, "usec": 0.0}
var _controller_frame_usec := []
var _idle_frame_usec := []
var _idle_frames_left := -1
var _scale_range := Vector2.ZERO
## Physics frames since the run started.
var _frame := 0


func _initialize() -> void:
	var error := PunchPair.read_options(_options, ["policy", "episodes", "out"])
	if error != "":
		_fail(error)
		return
	_episodes = PunchPair.json_list(_options.episodes)
	if _episodes.is_empty():
		_fail("--episodes must name a JSON file holding a non-empty list of episodes: %s" % _options.episodes)
		return
	for index in _episodes.size():
		var episode = _episodes[index]
		if not episode is Dictionary or not (episode as Dictionary).has("seed"):
			_fail("episode %d is not an object with a seed" % index)
			return
		if not episode.get("start", "guard") in ["guard", "after_punch"]:
			_fail("episode %d: start is guard or after_punch, not '%s'" % [index, episode.get("start")])
			return
		if episode.get("body") != null and episode.get("target") != null:
			_fail("episode %d moves both the body and the target's hook; one of them at a time" % index)
			return
	_record = _options.record == "1"
	_rows.resize(_episodes.size())
	DirAccess.make_dir_recursive_absolute(_options.out)
	if _record:
		for kind in KINDS:
			_files[kind] = FileAccess.open(_options.out.path_join("%s.f32" % kind), FileAccess.WRITE)
	_meta = {"policy": _options.policy, "episodes": _episodes.size(), "characters": int(_options.characters),
		"characters_per_world": int(_options["characters-per-world"]),
		"feature_names": Array(ClassDB.class_call_static("PunchSpec", "feature_names"))}


func _physics_process(_delta: float) -> bool:
	if _failed:
		return true
	_frame += 1
	var waiting := false
	for slot in _slots:
		if not slot.struck.is_empty() and slot.lead_frames < 0 and slot.struck_open:
			_measure_struck(slot)
	for slot in _slots:
		if slot.lead_frames > 0:
			slot.lead_frames -= 1
			if slot.lead_frames == 0 and not _punch(slot):
				return true
			waiting = true
	if waiting or _pending > 0:
		return false
	if not _slots.is_empty():
		var idle := int(_options["idle-frames"])
		if _idle_frames_left < 0 and idle > 0:
			_controller_frame_usec.append(PunchProbe.take_frame_cost_usec())
			_idle_frames_left = idle + 1
			_idle_frame_usec.append([])
		if _idle_frames_left > 0:
			# Frame by frame: a median is not moved by the rare frame the OS takes the thread away.
			_idle_frame_usec[-1].append(PunchProbe.take_frame_cost_usec())
			_idle_frames_left -= 1
			if _idle_frames_left > 0:
				return false
			_idle_frame_usec[-1].pop_front()  # the frame the punches ended in
		_idle_frames_left = -1
		_collect_batch()
	if _next < _episodes.size():
		_start_batch()
		return false
	_finish()
	return true


func _start_batch() -> void:
	var count := mini(int(_options.characters), _episodes.size() - _next)
	var per_world := clampi(int(_options["characters-per-world"]), 1, PunchPair.MAX_PER_WORLD)
	var default_offset := PunchSpec.default_target_offset()
	var arena: SubViewport
	for index in count:
		if index % per_world == 0:
			arena = PunchPair.add_arena(root)
			_arenas.append(arena)
		var episode: Dictionary = _episodes[_next + index]
		var slot := _add_episode(arena, index % per_world, episode, _next + index, default_offset)
		if slot == null:
			return
		_slots.append(slot)
	_next += count
	_pending = count
	PunchProbe.take_inference_counts()
	PunchProbe.take_frame_cost_usec()
	for slot in _slots:
		if slot.motion != null and not slot.motion_with_punch:
			slot.motion.lunge_start_s = float(_episodes[slot.row[-1]].get("lead_s", 0.0))
			_start_motion(slot)
	for slot in _slots:
		if slot.lead_frames == 0 and not _punch(slot):
			return


## Builds one episode's pair in `arena`'s world slot `layer_slot`; null when it cannot (the run has failed).
func _add_episode(arena: SubViewport, layer_slot: int, episode: Dictionary, index: int, default_offset: Vector3) -> Slot:
	var slot := Slot.new()
	var placement: Dictionary = episode.get("placement", {})
	var offset := Vector3(placement.get("side_m", default_offset.x), placement.get("height_m", default_offset.y),
		placement.get("distance_m", default_offset.z))
	var swing := Vector3(placement.get("velocity_side_mps", 0.0), 0.0, placement.get("velocity_forward_mps", 0.0))
	# A move (the policy as the moveset's policy for it, thrown in the episode's stance): a left-hand move punches
	# at the mirror image of the placement, drawn from the right hand's reach volume.
	var move := StringName(episode.get("move", ""))
	var combo: Array = episode.get("combo", [])
	var stance := PunchController.SOUTHPAW if episode.get("stance", "orthodox") == "southpaw" else PunchController.ORTHODOX
	if move != &"" and PunchController.hand_for(move, stance) == &"left":
		offset.x = -offset.x
		swing.x = -swing.x
	var body_motion = episode.get("body")
	var target_motion = episode.get("target")
	var parent: Node = arena
	var holder: Holder = null
	if body_motion != null or target_motion != null:
		holder = Holder.new()
		arena.add_child(holder)
		parent = holder
	var controller := PunchPair.add(parent, layer_slot, Vector3.ZERO, offset, _options.policy,
		float(episode.get("sigma", 0.0)), int(episode.get("noise_decisions", -1)), int(episode.seed), swing)
	if move != &"":
		if PunchController.hand_for(move, stance) == &"":
			_fail("the episode's move '%s' is none of the six" % move)
			return null
		var moveset := PunchMoveset.new()
		moveset.set(move, controller.get("policy"))
		controller.set("moveset", moveset)
		controller.set("stance", stance)
		slot.move = move
	if not combo.is_empty():
		if move != &"":
			_fail("episode %d has both a move and a combo" % index)
			return null
		var moveset: Resource = load(STANCE_MOVESET if bool(episode.get("stance_pose", false)) else ADDON_MOVESET)
		if episode.has("cancel_delay_s"):
			moveset = moveset.duplicate()
			for each in MOVES:
				moveset.set("%s_cancel_delay_s" % each, float(episode.cancel_delay_s))
		controller.set("moveset", moveset)
		controller.set("stance", stance)
		slot.combo = combo
	controller.set("stance_pose", bool(episode.get("stance_pose", false)))
	controller.set("guard_first", bool(episode.get("guard_first", true)))
	if _record:
		PunchProbe.set_recording(controller, true)
	var until_recovered := bool(episode.get("until_recovered", false))
	controller.set("auto_recover", until_recovered)  # else: each batch's scene is freed after its punches
	var character: Node3D = controller.get("character")
	_scale_range = character.call("arm_scale_range")
	var arms: Array = episode.get("arms", [1.0, 1.0])
	var refused := PunchPair.size_arms(character, Vector2(arms[0], arms[-1]))
	if refused != "":
		_fail(refused)
		return null
	var sized: Vector3 = character.call("arm_lengths")
	var bag: RigidBody3D = controller.get("target")
	# What the punch aims at and counts hits on: the bag, or a defender's head.
	var target: CollisionObject3D = bag
	if episode.has("defender"):
		if body_motion != null or target_motion != null or not combo.is_empty() or episode.get("start", "guard") != "guard":
			_fail("episode %d: a defender stands: no body or target motion, no combo, a start from guard" % index)
			return null
		target = _add_defender(controller, bag, layer_slot, offset, episode.defender, slot)
		bag = null
	slot.controller = controller
	slot.row = [0, 0, 0.0, "", 0.0, sized.x, sized.y, sized.z, [], {}, index]
	if holder != null:
		var hook: PinJoint3D = bag.get_parent().get_node("Hook")
		# The body the hook is pinned to, placed before it enters the tree (a kinematic body moved into place
		# afterwards would sweep there in the first physics step and yank the bag).
		var anchor: AnimatableBody3D
		if body_motion != null:
			anchor = AnimatableBody3D.new()
			anchor.sync_to_physics = false  # follows its parent, the holder
			anchor.position = hook.global_position
			holder.add_child(anchor)
			# The bag hangs from the carried hook under physics: were it moved with its parent too, it would be
			# teleported every frame and also fly on at the velocity it starts with.
			bag.top_level = true
			slot.moved = holder
			slot.motion = Motion.new(body_motion)
		else:
			var moving_hook := MovingHook.new()
			moving_hook.position = hook.global_position
			arena.add_child(moving_hook)
			anchor = moving_hook
			slot.moved = moving_hook
			slot.moved_from = moving_hook.position
			slot.motion = Motion.new(target_motion)
		anchor.collision_layer = 0
		anchor.collision_mask = 0
		hook.node_a = hook.get_path_to(anchor)
		slot.bag = bag
	var lead_s := maxf(float(episode.get("lead_s", 0.0)), 0.0)
	slot.motion_with_punch = target_motion != null or lead_s == 0.0
	slot.lead_frames = roundi(lead_s * Engine.physics_ticks_per_second)
	if episode.has("struck"):
		slot.struck = episode.struck
		slot.lead_frames = maxi(slot.lead_frames, 2)  # standing in the tree a frame before the hit
		_listen_struck(slot, controller, character)
		return slot
	var row := slot.row
	var timings: Array = row[8]
	var bag_start := [bag.global_transform, bag.linear_velocity, bag.angular_velocity] if bag != null else []
	var reset_target := bool(episode.get("reset_target", false))
	controller.connect("punch_started", func(_move, _hand, combo_index: int):
		if reset_target and combo_index > 0:
			_put_back(bag, bag_start)
		timings.append([_frame - slot.commanded_at, -1]))
	controller.connect("hit", func(impulse, _speed, _position, body, _push, _hand, _part, _blocked):
		if body == target:
			row[0] += 1
			if target != bag:
				row[9]["head_impulse_ns"] = impulse
			if not timings.is_empty() and timings[-1][1] < 0:
				timings[-1][1] = _frame - slot.commanded_at)
	var finish := func() -> void:
		_stop_motion(slot)
		_pending -= 1
	# A combo's string ends at `combo_finished`; `recovered` before then (a long cancel delay) is between punches.
	var string_done := [false]
	controller.connect("combo_finished", func(_landed, _thrown):
		string_done[0] = true
		if not until_recovered and not combo.is_empty():
			finish.call())
	if until_recovered:
		controller.connect("recovered", func():
			if string_done[0]:
				timings.append(_frame - slot.commanded_at)
				finish.call())
	controller.connect("target_out_of_reach", func(offset_now: Vector3, nearest: Vector3):
		row[1] += 1
		row[2] = snappedf(offset_now.distance_to(character.global_transform.affine_inverse() * nearest), 0.001))
	var lead_punches := [1 if episode.get("start", "guard") == "after_punch" else 0]
	controller.connect("punch_finished", func(metrics: Dictionary):
		if metrics.get("ended") == "error":
			_fail("a punch stopped on an error: %s" % metrics.get("error", "see the error above"))
			return
		if lead_punches[0] > 0:
			lead_punches[0] -= 1
			# The character starts where its earlier punch left it; the bag hangs as placed again.
			_put_back(bag, bag_start)
			row[0] = 0
			row[1] = 0
			row[2] = 0.0
			timings.clear()
			slot.commanded_at = _frame
			controller.call("punch", slot.move)
			return
		row[3] = metrics.get("ended", "")
		if target != bag:
			row[9]["outcome"] = metrics.get("outcome", "")
		if slot.combo.is_empty() and not until_recovered:
			finish.call())
	return slot


## A defending character in place of `bag` (freed), facing the puncher of `controller`, its root `offset`'s distance
## and side from the puncher's, on the bag's collision layers, with a controller of its own (blocking from the start
## with `defender_spec.blocks`); returns its head or torso (`defender_spec.part`), which the punch now aims at. With
## `defender_spec.motion` it stands in a holder of its own (as a game's fighter in its CharacterBody3D) that `slot`
## moves from the episode's start (or the punch's, with no lead), in the defender's own frame.
func _add_defender(controller: Node, bag: RigidBody3D, layer_slot: int, offset: Vector3, defender_spec: Dictionary,
		slot: Slot) -> CollisionObject3D:
	var sandbag := bag.get_parent()
	var parent := sandbag.get_parent()
	parent.remove_child(sandbag)
	sandbag.free()
	var puncher: Node3D = controller.get("character")
	var defender: Node3D = PunchPair.CHARACTER_SCENE.instantiate()
	var turned_rad := deg_to_rad(float(defender_spec.get("turned_deg", 0.0)))
	var placed := Transform3D(Basis(Vector3.UP, PI + turned_rad), puncher.position + Vector3(offset.x, 0.0, offset.z))
	var layer := 1 << (2 * layer_slot)
	PunchPair.set_layers(defender, layer << 1, layer)
	if defender_spec.has("motion"):
		var holder := Holder.new()
		holder.transform = placed
		parent.add_child(holder)
		holder.add_child(defender)
		slot.moved = holder
		slot.moved_from = placed.origin
		slot.motion = Motion.new(defender_spec.motion)
	else:
		defender.transform = placed
		parent.add_child(defender)
	var head_up_m := float(defender_spec.get("head_up_m", 0.0))
	if head_up_m != 0.0 and not defender.call("size_head", defender.call("shoulder_to_crown_m") + head_up_m):
		_fail("the defender's head could not be moved %.3f m up its neck" % head_up_m)
	var aimed_at: RigidBody3D = defender.get_node("Torso" if defender_spec.get("part", "head") == "torso" else "Head")
	controller.set("target", aimed_at)
	var guard: Node = ClassDB.instantiate("PunchController")
	guard.set("character", defender)
	guard.set("target", puncher.get_node("Torso"))
	parent.add_child(guard)
	if bool(defender_spec.get("blocks", false)):
		guard.call_deferred("block")
	return aimed_at


## Hangs the bag as it was placed again: [transform, linear velocity, angular velocity].
func _put_back(bag: RigidBody3D, placed: Array) -> void:
	bag.global_transform = placed[0]
	bag.linear_velocity = placed[1]
	bag.angular_velocity = placed[2]


## Starts a slot's motion: its node moves from this physics frame on, and the bag that hangs from it (or rides
## along with it) starts at its velocity.
func _start_motion(slot: Slot) -> void:
	slot.moved.set("motion", slot.motion)
	if slot.bag != null:
		slot.bag.linear_velocity = slot.motion.start_velocity(slot.moved)


## Stops a slot's moving node (if it has one) and records how far it went.
func _stop_motion(slot: Slot) -> void:
	if slot.moved != null:
		slot.moved.set("motion", null)
		slot.row[4] = snappedf(slot.moved.global_position.distance_to(slot.moved_from), 0.001)


## Starts a slot's punch (and the motion that starts with it), or strikes it; false when the controller refused.
func _punch(slot: Slot) -> bool:
	slot.lead_frames = -1
	slot.commanded_at = _frame
	if not slot.struck.is_empty():
		if not _strike(slot):
			return false
	else:
		var thrown: bool = slot.controller.call("combo", slot.combo) if not slot.combo.is_empty() \
			else slot.controller.call("punch", slot.move)
		if not thrown:
			_fail("PunchController refused to punch (see the error above)")
			return false
	if slot.motion != null and slot.motion_with_punch:
		_start_motion(slot)
	return true


## A struck character's episode: its figures as its controller reacts, ending once `recovered` has come and every body
## is back within `BACK_IN_GUARD_DEG` of its guard (`_measure_struck`).
func _listen_struck(slot: Slot, controller: Node, character: Node3D) -> void:
	var figures: Dictionary = slot.row[9]
	figures.merge({"peak_deg": 0.0, "head_moved_m": 0.0, "back_s": -1.0, "recovered_s": -1.0, "staggered": false,
		"knocked_down": false})
	controller.connect("staggered", func(_impulse_ns): figures.staggered = true)
	controller.connect("knocked_down", func(_impulse_ns):
		figures.knocked_down = true
		create_timer(1.0, true, true).timeout.connect(func(): controller.call("recover")))
	controller.connect("recovered", func():
		if figures.recovered_s < 0.0:
			figures.recovered_s = float(_frame - slot.commanded_at) / Engine.physics_ticks_per_second)
	slot.character = character


## The game's hit on a standing character: its guard noted, then `take_hit` on the part.
func _strike(slot: Slot) -> bool:
	var character: Node3D = slot.character
	for body in STRUCK_BODIES:
		slot.guard_rotations[body] = _rotation_in(character, body)
	slot.head_at = character.global_transform.affine_inverse() * character.get_node("Head").global_position
	var part := StringName(slot.struck.part)
	var at := {&"head": "Head/HeadMesh", &"left_arm": "UpperArmL", &"right_arm": "UpperArmR"}
	var point: Vector3 = character.get_node(at.get(part, "Torso")).global_position
	if part == &"torso":
		point += character.global_basis.y * 0.15
	var direction: Array = slot.struck.direction
	var impulse := character.global_basis * Vector3(direction[0], direction[1], direction[2]) * float(slot.struck.impulse_ns)
	if not character.call("take_hit", part, impulse, point):
		_fail("PunchCharacter refused the episode's hit (see the error above)")
		return false
	return true


## How far a struck character's bodies and head are from where they were when the hit came.
func _measure_struck(slot: Slot) -> void:
	var character: Node3D = slot.character
	var figures: Dictionary = slot.row[9]
	var worst := 0.0
	for body in STRUCK_BODIES:
		worst = maxf(worst, rad_to_deg(_rotation_in(character, body).angle_to(slot.guard_rotations[body])))
	figures.peak_deg = maxf(figures.peak_deg, worst)
	var head: Vector3 = character.global_transform.affine_inverse() * character.get_node("Head").global_position
	figures.head_moved_m = maxf(figures.head_moved_m, head.distance_to(slot.head_at))
	if worst > BACK_IN_GUARD_DEG:
		slot.back_at = -1
	elif slot.back_at < 0 and figures.peak_deg > BACK_IN_GUARD_DEG:
		slot.back_at = _frame
	var back: bool = slot.back_at >= 0 or figures.peak_deg <= BACK_IN_GUARD_DEG
	var watched_s: float = float(_frame - slot.commanded_at) / Engine.physics_ticks_per_second
	if (figures.recovered_s >= 0.0 and back) or watched_s >= STRUCK_WATCH_S:
		if slot.back_at >= 0:
			figures.back_s = float(slot.back_at - slot.commanded_at) / Engine.physics_ticks_per_second
		elif back:
			figures.back_s = 0.0
		_stop_motion(slot)
		slot.struck_open = false
		_pending -= 1


## A body's rotation in its character's frame.
func _rotation_in(character: Node3D, body: String) -> Quaternion:
	var node: Node3D = character.get_node(body)
	return (character.global_basis.inverse() * node.global_basis).get_rotation_quaternion()


func _collect_batch() -> void:
	var counts: Dictionary = PunchProbe.take_inference_counts()
	for key in _inference:
		_inference[key] += counts[key]
	if int(_options["idle-frames"]) == 0:  # else taken before the idle frames
		_controller_frame_usec.append(PunchProbe.take_frame_cost_usec())
	for slot in _slots:
		var index: int = slot.row.pop_back()
		_rows[index] = slot.row
		if _record:
			var record: Dictionary = PunchProbe.last_punch_record(slot.controller)
			_meta["frames"] = record.frames
			_meta["decisions"] = record.decisions
			for kind in KINDS:
				_files[kind].store_buffer((record[kind] as PackedFloat32Array).to_byte_array())
	print("EVALUATE_PROGRESS %d %d" % [_next, _episodes.size()])
	PunchPair.free_arenas(_arenas)
	_slots.clear()


func _finish() -> void:
	for kind in _files:
		_files[kind].close()
	_files.clear()
	_meta["rows"] = _rows
	_meta["arm_scale_range"] = [_scale_range.x, _scale_range.y]
	_meta["inference"] = _inference
	_meta["controller_frame_usec_per_batch"] = _controller_frame_usec
	_meta["idle_controller_frame_usec_per_batch"] = _idle_frame_usec
	PunchPair.write_json(_options.out.path_join("episodes.json"), _meta)
	print("EVALUATE_DONE")


func _fail(message: String) -> void:
	printerr("error: evaluate: ", message)
	_failed = true
	quit(2)
