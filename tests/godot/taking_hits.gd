## Taking hits, measured from the bodies: characters of the addon's scene (each with a PunchController that does not
## punch) struck by the game's `take_hit` on the torso, from the side and from the front, at several impulses; a punch
## struck while it runs, with and without `hyper_armour`; refused hits; and a character punched by another's
## controller (its `hit_taken`, the attacker's `punch_finished` outcome) and a punch that strikes nothing.
## The 60 N s hit again on a turned, a walking and a short-armed character. For each struck character: the largest
## turn of any body away from its guard (degrees, in the character's frame), the head's largest move (m), when every
## body was back within 10 degrees of it and when `recovered` came (s after the hit), and the
## `hit_taken`, `staggered` and `knocked_down` signals; a knocked-down character gets `recover()` a second after its
## hit. Prints `TAKING_HITS <json>` and quits.
extends SceneTree

const CHARACTER_SCENE := preload("res://addons/punch_controller/scenes/punch_character.tscn")
const SANDBAG_SCENE := preload("res://addons/punch_controller/scenes/punch_sandbag.tscn")
const POLICY := "res://addons/punch_controller/policies/straight.onnx"
const BODIES := ["Torso", "UpperArmR", "ForearmR", "UpperArmL", "ForearmL", "Head"]
## Impulses (N s) the game's hits carry: a punch on a sandbag is 5-10 N s, a real straight about 27.
const IMPULSES_NS := [10.0, 30.0, 60.0]
const BACK_IN_GUARD_DEG := 10.0
const WATCH_S := 3.0

## One struck character and what was seen of it.
class Watched:
	var character: Node3D
	var controller: PunchController
	var rest := {}
	var struck_at := -1
	var peak_deg := 0.0
	var back_at := -1
	var recovered_at := -1
	var hits_taken: Array = []
	## The `hit`s its own fists struck: [part, blocked].
	var hits: Array = []
	var finished: Array = []
	var staggered: Array = []
	var knocked_down: Array = []
	var down_after_1s := false
	var head_rest := Vector3.ZERO
	var head_moved_m := 0.0


var _frame := 0
var _watched: Array[Watched] = []
var _report := {"struck": [], "refused": [], "punch_struck": {}, "duel": {}}
var _duel := {}


func _initialize() -> void:
	var x := 0.0
	for impulse in IMPULSES_NS:
		# The character faces +Z with +X its left: a hit from the front pushes it back (-Z), one from its right
		# pushes it to its left (+X).
		for from in ["front", "right"]:
			var push: Vector3 = (Vector3.FORWARD if from == "front" else Vector3.RIGHT) * impulse
			_watched.append(_standing(Vector3(x, 0, 0), {"impulse_ns": impulse, "from": from, "push": push}))
			x += 3.0
	# The head, on its neck: struck on the forehead from the front and from the side.
	for impulse in [30.0, 60.0]:
		for from in ["front", "right"]:
			var push: Vector3 = (Vector3.FORWARD if from == "front" else Vector3.RIGHT) * impulse
			_watched.append(_standing(Vector3(x, 0, 0), {"impulse_ns": impulse, "from": from, "push": push,
				"part": "head"}))
			x += 3.0
	# A knock-down: the body hangs limp until the game calls `recover()`, a second later.
	_watched.append(_standing(Vector3(x, 0, 0), {"impulse_ns": 320.0, "from": "front", "push": Vector3.FORWARD * 320.0,
		"recover_after_s": 1.0}))
	x += 3.0
	# The same 60 N s from the front on a character turned away from the world's axes, one walking forward at
	# 0.7 m/s and one with arms 0.8 times the scene's: the hit is in the character's own frame.
	for variant in ["turned", "walking", "short arms"]:
		var watched := _standing(Vector3(x, 0, 0), {"impulse_ns": 60.0, "from": "front", "push": Vector3.FORWARD * 60.0,
			"variant": variant})
		if variant == "turned":
			watched.character.rotate_y(deg_to_rad(130.0))
		_watched.append(watched)
		x += 3.0
	# And 30 N s on the side of the head of a turned and of a walking character: the neck's snap is in its frame too.
	for variant in ["turned", "walking"]:
		var watched := _standing(Vector3(x, 0, 0), {"impulse_ns": 30.0, "from": "right", "push": Vector3.RIGHT * 30.0,
			"variant": variant, "part": "head"})
		if variant == "turned":
			watched.character.rotate_y(deg_to_rad(130.0))
		_watched.append(watched)
		x += 3.0
	for armour in [false, true]:
		_watched.append(_punching(Vector3(x, 0, 0), armour))
		x += 3.0
	_add_duel(Vector3(x, 0, 0))


## A character standing in guard, to be struck on the chest at frame 30.
func _standing(origin: Vector3, hit: Dictionary) -> Watched:
	var watched := _add(origin)
	watched.set_meta("hit", hit)
	return watched


## A character punching a sandbag, struck 12 frames into its punch (`hyper_armour` as given).
func _punching(origin: Vector3, armour: bool) -> Watched:
	var watched := _add(origin)
	var bag: Node3D = SANDBAG_SCENE.instantiate()
	bag.position = origin + PunchSpec.default_target_offset()
	root.add_child(bag)
	watched.controller.target = bag.get_node("Bag")
	watched.controller.hyper_armour = armour
	watched.set_meta("armour", armour)
	return watched


func _add(origin: Vector3) -> Watched:
	var watched := Watched.new()
	watched.character = CHARACTER_SCENE.instantiate()
	watched.character.position = origin
	root.add_child(watched.character)
	watched.controller = PunchController.new()
	watched.controller.character = watched.character
	watched.controller.policy = load(POLICY)
	root.add_child(watched.controller)
	watched.character.hit_taken.connect(func(part, impulse, point, from, bone):
		watched.hits_taken.append({"part": part, "impulse_ns": snappedf(impulse.length(), 0.01), "from": from != null,
			"at": _frame, "point": [point.x, point.y, point.z], "bone": bone}))
	watched.controller.hit.connect(func(_impulse, _speed, _position, _body, _push, _hand, part, blocked):
		watched.hits.append([part, blocked]))
	watched.controller.punch_finished.connect(func(metrics): watched.finished.append({"ended": metrics.ended,
		"outcome": metrics.outcome}))
	watched.controller.recovered.connect(func(): if watched.struck_at >= 0 and watched.recovered_at < 0:
		watched.recovered_at = _frame)
	watched.controller.staggered.connect(func(impulse_ns): watched.staggered.append(snappedf(impulse_ns, 0.01)))
	watched.controller.knocked_down.connect(func(impulse_ns): watched.knocked_down.append(snappedf(impulse_ns, 0.01)))
	return watched


## Two characters facing each other, each with a controller: the first punches the second's torso at frame 30;
## a third punches a marker 3 m away, out of any reach, and strikes nothing.
func _add_duel(origin: Vector3) -> void:
	var attacker := _add(origin)
	var struck := _add(origin + Vector3(0, 0, PunchSpec.default_target_offset().z))
	struck.character.rotate_y(PI)
	attacker.controller.target = struck.character.get_node("Torso")
	var whiffer := _add(origin + Vector3(3, 0, 0))
	var far := Marker3D.new()
	far.position = origin + Vector3(3, 1.3, 3)
	root.add_child(far)
	whiffer.controller.target = far
	_duel = {"attacker": attacker, "struck": struck, "whiffer": whiffer}


func _physics_process(_delta: float) -> bool:
	_frame += 1
	for watched in _watched:
		if watched.has_meta("hit") and watched.get_meta("hit").get("variant") == "walking":
			watched.character.position += watched.character.global_basis.z * 0.7 / Engine.physics_ticks_per_second
	if _frame == 1:  # the characters are set up by now
		for watched in _watched:
			if watched.has_meta("hit") and watched.get_meta("hit").get("variant") == "short arms":
				var lengths: Vector3 = watched.character.arm_lengths()
				watched.character.size_arms(lengths.x * 0.8, lengths.y * 0.8, lengths.z)
	if _frame == 2:
		for watched in _watched:
			for body in BODIES:
				watched.rest[body] = _in_character_frame(watched, body)
	if _frame == 30:
		_strike_all()
	for watched in _watched:
		_measure(watched)
	if _frame == 30 + Engine.physics_ticks_per_second:
		for watched in _watched:
			if watched.has_meta("hit") and watched.get_meta("hit").has("recover_after_s"):
				watched.down_after_1s = watched.controller.is_knocked_down()
				watched.controller.recover()
	if _frame == 30 + 2 * Engine.physics_ticks_per_second:
		# Long after their punches ended: a controller that drove its character reacts to its next hit all the same.
		for watched in _watched:
			if watched.has_meta("armour"):
				var chest: Vector3 = watched.character.get_node("Torso").global_position
				watched.character.take_hit(&"torso", watched.character.global_basis * Vector3.FORWARD * 60.0, chest)
	if _frame == 30 + 12:
		for watched in _watched:
			if watched.has_meta("armour"):
				_strike(watched, Vector3.FORWARD * 20.0)
	if _frame < 30 + roundi(WATCH_S * Engine.physics_ticks_per_second):
		return false
	_finish()
	return true


func _strike_all() -> void:
	for watched in _watched:
		if watched.has_meta("hit"):
			_strike(watched, watched.get_meta("hit").push)
		elif watched.has_meta("armour"):
			watched.controller.punch()
	_duel.attacker.controller.punch()
	_duel.whiffer.controller.punch()
	# Hits a game must not be able to land: each refused with an error, nothing pushed.
	var character: Node3D = _duel.whiffer.character
	var chest: Vector3 = character.get_node("Torso").global_position
	for bad in [[&"tail", Vector3.BACK, chest], [&"torso", Vector3(NAN, 0, 0), chest], [&"torso", Vector3.BACK * 5000.0, chest],
			[&"head", Vector3.BACK, Vector3(INF, 0, 0)]]:
		_report.refused.append(character.take_hit(bad[0], bad[1], bad[2]))


## The game's hit on a character's chest, 15 cm above the torso's centre, or on its forehead, 3 cm above the head's
## centre; `push` in the character's frame.
func _strike(watched: Watched, push: Vector3) -> void:
	var part := StringName(watched.get_meta("hit", {}).get("part", "torso"))
	var body: Node3D = watched.character.get_node("Head" if part == &"head" else "Torso")
	var point := body.global_position + Vector3(0, 0.03 if part == &"head" else 0.15, 0)
	watched.struck_at = _frame
	watched.peak_deg = 0.0
	watched.back_at = -1
	watched.head_rest = _head_in_character_frame(watched)
	if not watched.character.take_hit(part, watched.character.global_basis * push, point):
		push_error("take_hit refused a hit it should take")


func _measure(watched: Watched) -> void:
	if watched.struck_at < 0 or watched.rest.is_empty():
		return
	var worst := 0.0
	for body in BODIES:
		var now := _in_character_frame(watched, body)
		worst = maxf(worst, rad_to_deg(now.angle_to(watched.rest[body])))
	watched.peak_deg = maxf(watched.peak_deg, worst)
	watched.head_moved_m = maxf(watched.head_moved_m, _head_in_character_frame(watched).distance_to(watched.head_rest))
	if watched.back_at < 0 and watched.peak_deg > BACK_IN_GUARD_DEG and worst <= BACK_IN_GUARD_DEG:
		watched.back_at = _frame
	elif worst > BACK_IN_GUARD_DEG:
		watched.back_at = -1


func _in_character_frame(watched: Watched, body: String) -> Quaternion:
	var node: Node3D = watched.character.get_node(body)
	return (watched.character.global_basis.inverse() * node.global_basis).get_rotation_quaternion()


func _head_in_character_frame(watched: Watched) -> Vector3:
	return watched.character.global_transform.affine_inverse() * watched.character.get_node("Head").global_position


func _seconds(frames: int) -> float:
	return snappedf(float(frames) / Engine.physics_ticks_per_second, 0.001)


func _finish() -> void:
	for watched in _watched:
		var row := {"peak_deg": snappedf(watched.peak_deg, 0.1),
			"back_in_guard_s": _seconds(watched.back_at - watched.struck_at) if watched.back_at >= 0 else -1.0,
			"recovered_s": _seconds(watched.recovered_at - watched.struck_at) if watched.recovered_at >= 0 else -1.0,
			"hits_taken": watched.hits_taken, "finished": watched.finished, "staggered": watched.staggered,
			"knocked_down": watched.knocked_down, "down_after_1s": watched.down_after_1s}
		if watched.has_meta("hit"):
			var hit: Dictionary = watched.get_meta("hit")
			var arms: Vector3 = watched.character.arm_lengths()
			row.merge({"impulse_ns": hit.impulse_ns, "from": hit.from, "variant": hit.get("variant", ""),
				"part": hit.get("part", "torso"), "head_moved_m": snappedf(watched.head_moved_m, 0.001),
				"arm_m": snappedf(arms.x + arms.y, 0.001)})
			_report.struck.append(row)
		else:
			_report.punch_struck["armour" if watched.get_meta("armour") else "no_armour"] = row
	for role in _duel:
		var watched: Watched = _duel[role]
		_report.duel[role] = {"hits_taken": watched.hits_taken, "finished": watched.finished, "hits": watched.hits}
	var character: Node3D = _duel.struck.character
	_report.parts = [character.part_of(character.get_node("ForearmL")), character.part_of(character.get_node("UpperArmR")),
		character.part_of(character.get_node("Torso")), character.part_of(character.get_node("Head")),
		character.part_of(_duel.attacker.character.get_node("Torso")),
		character.part_of(null)]
	print("TAKING_HITS ", JSON.stringify(_report))
	quit(0)
