## Punches on the move, as a game moves its characters: counts, for each motion case, placement and sigma,
## whether a policy's punch through PunchController hits its target. For `punch eval-moving`
## (trainer/punch_trainer/pipelines/moving_eval.py, which defines the cases; docs/moving.md describes them).
##
## tools/godot --headless --fixed-fps 120 --path godot_project --script res://tools/moving_hits.gd -- \
##     --policy=PATH --bags=FILE.json --cases=FILE.json --out=FILE.json [--sigmas=0,0.3] [--seed=0]
##     [--characters=64] [--characters-per-world=16] [--lead-s=0.5] [--arms=U,F]
##
## `--arms`: every character's upper arm and forearm sized to U and F times its scene's (`PunchPair.size_arms`,
## as sized_hits.gd sizes them) right after it enters the tree; a size `size_arms` refuses ends the run with exit
## code 2.
##
## Every punch (one per sigma, case and placement) is built fresh, side by side like replay.gd's: a SubViewport
## with its own World3D per 16 characters, two collision layers per character (tools/punch_pair.gd). Each
## character and its PunchController are children of a holder Node3D, the node a game would move (its
## CharacterBody3D). A case moves, in a `_physics_process` of its own every physics frame, as a game moves a
## CharacterBody3D, until the punch finishes; a character that moves starts `--lead-s` before its punch (it is
## walking or turning when it punches, and its bag rides along at its velocity), except for its lunge, which
## starts with the punch; a moving target starts with the punch:
##
## - `target: "ride"`: the holder, with the character's sandbag riding along (the sandbag's scene root is a
##   child of the same holder, so the bag stays where it was relative to the character). A joint does not
##   follow its node (Godot's Joint3D is configured once, when it enters the tree), so the sandbag's hook is
##   pinned to a kinematic body (AnimatableBody3D) that is a child of the holder: without it the hook would stay
##   where it was in the world and drag the bag back. The bag itself is `top_level` (not teleported with the
##   holder): it hangs from the carried hook under physics, starting at the holder's velocity, as training's
##   `bag_rides` carries it.
## - `target: "moving"`: the character stands; the sandbag's hook is pinned to a kinematic body that moves
##   itself every physics frame (`sync_to_physics`, so physics knows its velocity), and the bag starts with the
##   hook's velocity, so it hangs steadily below the moving hook (a hanging bag can only be moved by its hook:
##   teleporting the bag every frame would be no physical motion at all). A fist's push then swings it on
##   the hook, as it swings a bag that stands still.
##
## A motion (JSON, the character's frame at the start: +Z ahead, +X its left, +Y up): `velocity_mps`
## [left, up, forward] in the moving node's own frame (so turning while walking walks an arc), `turn_dps`
## (about +Y, positive turns left; about the character's root), `lunge_m` over `lunge_s` (forward,
## minimum-jerk: starts and stops smoothly, begins with the punch), `bob_m` at `bob_hz` (vertical, a sine).
##
## A hit: the controller's `hit` signal with the target's Bag as the body, during the punch. Punch i of sigma
## index s at placement p (any case) uses noise seed seed * 1000003 + s * 100003 + p, so every case sees the
## same noise at the same placement. The output JSON holds one row per punch: [sigma index, case index,
## placement index, hits on the target, target_out_of_reach signals, how it ended, how far the moved node went
## (m, straight line), how far outside the reach volume the target was when the punch started (m, 0 inside)].
## Progress lines:
## `MOVING_PROGRESS done total`.
extends SceneTree

const PunchPair := preload("res://tools/punch_pair.gd")


## The node a game moves: the character's holder (ride mode) or the target's hook (moving mode) run the same motion.
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


## The sandbag's hook in the moving-target mode: a kinematic body that moves itself while `motion` is set.
class MovingHook extends AnimatableBody3D:
	var motion: Motion

	func _physics_process(delta: float) -> void:
		if motion != null:
			motion.advance(self, delta)


var _options := {
	"policy": "", "bags": "", "cases": "", "out": "", "sigmas": "0", "seed": "0", "characters": "64",
	"characters-per-world": "16", "lead-s": "0", "arms": "1,1",
}
var _bags: Array = []
var _cases: Array = []
var _sigmas := PackedFloat32Array()
var _arms := Vector2.ONE  # (upper arm, forearm) scale
var _episodes: Array = []  # [sigma index, case index, placement index]
var _next := 0
var _rows: Array = []
var _arenas: Array[SubViewport] = []
var _pending := 0
var _failed := false
## The batch's punches wait this many physics frames (their characters' lead), then start.
var _lead_frames_left := 0
var _starts: Array = []  # per slot: [controller, the node that moves, its Motion, bag or null, starts with punch]


func _initialize() -> void:
	var error := PunchPair.read_options(_options, ["policy", "bags", "cases", "out"])
	if error != "":
		_fail(error)
		return
	_sigmas = PunchPair.floats(_options.sigmas)
	var arms := PunchPair.floats(_options.arms)
	_arms = Vector2(arms[0], arms[-1])
	_bags = PunchPair.json_list(_options.bags)
	_cases = PunchPair.json_list(_options.cases)
	if _bags.is_empty() or _cases.is_empty():
		_fail("--bags and --cases must name JSON files holding non-empty lists")
		return
	for case in _cases:
		if not case.get("target") in ["ride", "moving"]:
			_fail("case '%s': target is 'ride' or 'moving', not '%s'" % [case.get("name"), case.get("target")])
			return
	for sigma_index in _sigmas.size():
		for case_index in _cases.size():
			for placement_index in _bags.size():
				_episodes.append([sigma_index, case_index, placement_index])


func _physics_process(_delta: float) -> bool:
	if _failed:
		return true
	if _lead_frames_left > 0:
		_lead_frames_left -= 1
		if _lead_frames_left == 0:
			_start_punches()
		return false
	if _pending > 0:
		return false
	if not _arenas.is_empty():
		PunchPair.free_arenas(_arenas)
		print("MOVING_PROGRESS %d %d" % [_next, _episodes.size()])
	if _next < _episodes.size():
		_start_batch()
		return false
	PunchPair.write_json(_options.out, {"policy": _options.policy, "sigmas": Array(_sigmas),
		"seed": int(_options.seed), "arms": [_arms.x, _arms.y], "rows": _rows})
	print("MOVING_DONE")
	return true


func _start_batch() -> void:
	var count := mini(int(_options.characters), _episodes.size() - _next)
	var per_world := clampi(int(_options["characters-per-world"]), 1, PunchPair.MAX_PER_WORLD)
	var arena: SubViewport
	var controllers: Array[Node] = []
	var motions: Array = []  # [the node that moves, its Motion, the bag that starts with its velocity or null]
	for slot in count:
		if slot % per_world == 0:
			arena = PunchPair.add_arena(root)
			_arenas.append(arena)
		var episode: Array = _episodes[_next + slot]
		var entry: Dictionary = _bags[episode[2]]
		var case: Dictionary = _cases[episode[1]]
		var seed := int(_options.seed) * 1000003 + int(episode[0]) * 100003 + int(episode[2])
		var holder := Holder.new()
		arena.add_child(holder)
		var controller := PunchPair.add(holder, slot % per_world, Vector3.ZERO,
			Vector3(entry.side_m, entry.height_m, entry.distance_m), _options.policy, _sigmas[episode[0]], -1, seed)
		controller.set("auto_recover", false)  # each batch's scene is freed after its punches
		var refused := PunchPair.size_arms(controller.get("character"), _arms)
		if refused != "":
			_fail(refused)
			return
		var bag: RigidBody3D = controller.get("target")
		var hook: PinJoint3D = bag.get_parent().get_node("Hook")
		# The body the hook is pinned to, placed before it enters the tree (a kinematic body moved into place
		# afterwards would sweep there in the first physics step and yank the bag).
		var anchor: AnimatableBody3D
		var motion := Motion.new(case)
		if case.target == "ride":
			anchor = AnimatableBody3D.new()
			anchor.sync_to_physics = false  # follows its parent, the holder
			anchor.position = hook.global_position
			holder.add_child(anchor)
			# The bag hangs from the carried hook under physics: were it moved with its parent too, it would be
			# teleported every frame and also fly on at the velocity it starts with.
			bag.top_level = true
			motions.append([holder, motion, bag])
		else:
			var moving_hook := MovingHook.new()
			moving_hook.position = hook.global_position
			arena.add_child(moving_hook)
			anchor = moving_hook
			motions.append([moving_hook, motion, bag])
		anchor.collision_layer = 0
		anchor.collision_mask = 0
		hook.node_a = hook.get_path_to(anchor)
		var row := [episode[0], episode[1], episode[2], 0, 0, "", 0.0, 0.0]
		controller.connect("hit", func(_impulse, _speed, _position, body, _push):
			if body == bag:
				row[3] += 1)
		var character: Node3D = controller.get("character")
		controller.connect("target_out_of_reach", func(offset: Vector3, nearest: Vector3):
			row[4] += 1
			row[7] = snappedf(offset.distance_to(character.global_transform.affine_inverse() * nearest), 0.001))
		controller.connect("punch_finished", func(metrics: Dictionary):
			row[5] = metrics.get("ended", "")
			if row[5] == "error":
				_fail("a punch stopped on an error: %s" % metrics.get("error", "see the error above"))
				return
			var moved_node: Node3D = motions[slot][0]
			moved_node.set("motion", null)
			row[6] = snappedf(moved_node.global_position.length(), 0.001)
			_rows.append(row)
			_pending -= 1)
		controllers.append(controller)
	_next += count
	_pending = count
	var lead_s := maxf(float(_options["lead-s"]), 0.0)
	_starts.clear()
	for slot in count:
		var moved: Array = motions[slot]
		var with_punch: bool = _cases[_episodes[_next - count + slot][1]].target == "moving" or lead_s == 0.0
		_starts.append([controllers[slot]] + moved + [with_punch])
		if not with_punch:
			(moved[1] as Motion).lunge_start_s = lead_s
			_start_motion(moved)
	_lead_frames_left = roundi(lead_s * Engine.physics_ticks_per_second)
	if _lead_frames_left == 0:
		_start_punches()


## Starts a motion: its node moves from this physics frame on, and the bag that hangs from it (or rides along
## with it) starts at its velocity.
func _start_motion(moved: Array) -> void:
	(moved[0] as Node3D).set("motion", moved[1])
	if moved[2] != null:
		(moved[2] as RigidBody3D).linear_velocity = (moved[1] as Motion).start_velocity(moved[0])


## Starts the batch's punches, and the motions that start with them.
func _start_punches() -> void:
	for start in _starts:
		if not start[0].call("punch"):
			_fail("PunchController refused to punch (see the error above)")
			return
		if start[4]:
			_start_motion(start.slice(1, 4))


func _fail(message: String) -> void:
	printerr("error: moving_hits: ", message)
	_failed = true
	quit(2)
