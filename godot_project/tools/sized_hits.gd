## Punches of characters whose arms are sized to other bodies: counts, for each arm scale, sigma and placement,
## whether a policy's punch through PunchController hits its target. For `punch eval-sizes`
## (trainer/punch_trainer/pipelines/sizes_eval.py; README, "Your own character").
##
## tools/godot --headless --fixed-fps 120 --path godot_project --script res://tools/sized_hits.gd -- \
##     --policy=PATH --bags=FILE.json --scales=0.75,1,1.25,0.7x0.85 --out=FILE.json [--sigmas=0,0.3] [--seed=0]
##     [--characters=64] [--characters-per-world=16]
##
## Every punch (one per scale, sigma and placement) is built fresh, side by side like moving_hits.gd's: a
## SubViewport with its own World3D per 16 characters, two collision layers per character (tools/punch_pair.gd).
## Right after it enters the tree, each character's arms are sized through `PunchCharacter.size_arms`: its upper
## arm and forearm (elbow to fist centre) times the scale (UxF: the upper arm times U, the forearm times F), from the lengths the character reports for its own
## scene (`arm_lengths()`), the shoulders as they are. A scale `size_arms` refuses (outside
## `PunchCharacter.arm_scale_range()`) ends the run with its error and exit code 2. The bag stays where the
## placement puts it, relative to the character's root, whatever the arms' size.
##
## A hit: the controller's `hit` signal with the target's Bag as the body, during the punch. The punch of scale
## index a, sigma index s at placement p uses noise seed seed * 1000003 + s * 100003 + p, so every scale sees the
## same noise at the same placement. The output JSON holds `arm_scale_range` ([low, high], the arm's accepted
## scale) and one row per punch: [scale index, sigma index, placement index, hits on the target,
## target_out_of_reach signals, how it ended, upper arm m, forearm m, shoulder width m (as `arm_lengths()`
## reports them after the sizing)]. Progress lines: `SIZED_PROGRESS done total`.
extends SceneTree

const PunchPair := preload("res://tools/punch_pair.gd")

var _options := {
	"policy": "", "bags": "", "scales": "", "out": "", "sigmas": "0", "seed": "0", "characters": "64",
	"characters-per-world": "16",
}
var _bags: Array = []
var _scales: Array[Vector2] = []  # (upper arm, forearm) scale
var _sigmas := PackedFloat32Array()
var _episodes: Array = []  # [scale index, sigma index, placement index]
var _next := 0
var _rows: Array = []
var _arenas: Array[SubViewport] = []
var _pending := 0
var _failed := false
var _scale_range := Vector2.ZERO


func _initialize() -> void:
	var error := PunchPair.read_options(_options, ["policy", "bags", "scales", "out"])
	if error != "":
		_fail(error)
		return
	for value in _options.scales.split(","):
		var parts: PackedStringArray = value.split("x")
		_scales.append(Vector2(float(parts[0]), float(parts[-1])))
	_sigmas = PunchPair.floats(_options.sigmas)
	_bags = PunchPair.json_list(_options.bags)
	if _bags.is_empty():
		_fail("--bags must name a JSON file holding a non-empty list")
		return
	for scale_index in _scales.size():
		for sigma_index in _sigmas.size():
			for placement_index in _bags.size():
				_episodes.append([scale_index, sigma_index, placement_index])


func _physics_process(_delta: float) -> bool:
	if _failed:
		return true
	if _pending > 0:
		return false
	if not _arenas.is_empty():
		PunchPair.free_arenas(_arenas)
		print("SIZED_PROGRESS %d %d" % [_next, _episodes.size()])
	if _next < _episodes.size():
		_start_batch()
		return false
	PunchPair.write_json(_options.out, {"policy": _options.policy, "sigmas": Array(_sigmas), "seed": int(_options.seed),
		"arm_scale_range": [_scale_range.x, _scale_range.y], "rows": _rows})
	print("SIZED_DONE")
	return true


func _start_batch() -> void:
	var count := mini(int(_options.characters), _episodes.size() - _next)
	var per_world := clampi(int(_options["characters-per-world"]), 1, PunchPair.MAX_PER_WORLD)
	var arena: SubViewport
	var controllers: Array[Node] = []
	for slot in count:
		if slot % per_world == 0:
			arena = PunchPair.add_arena(root)
			_arenas.append(arena)
		var episode: Array = _episodes[_next + slot]
		var entry: Dictionary = _bags[episode[2]]
		var scale: Vector2 = _scales[episode[0]]
		var seed := int(_options.seed) * 1000003 + int(episode[1]) * 100003 + int(episode[2])
		var controller := PunchPair.add(arena, slot % per_world, Vector3.ZERO,
			Vector3(entry.side_m, entry.height_m, entry.distance_m), _options.policy, _sigmas[episode[1]], -1, seed)
		controller.set("auto_recover", false)  # each batch's scene is freed after its punches
		var character: Node = controller.get("character")
		_scale_range = character.call("arm_scale_range")
		var refused := PunchPair.size_arms(character, scale)
		if refused != "":
			_fail(refused)
			return
		var sized: Vector3 = character.call("arm_lengths")
		var bag: RigidBody3D = controller.get("target")
		var row := [episode[0], episode[1], episode[2], 0, 0, "", sized.x, sized.y, sized.z]
		controller.connect("hit", func(_impulse, _speed, _position, body, _push):
			if body == bag:
				row[3] += 1)
		controller.connect("target_out_of_reach", func(_offset, _nearest): row[4] += 1)
		controller.connect("punch_finished", func(metrics: Dictionary):
			row[5] = metrics.get("ended", "")
			if row[5] == "error":
				_fail("a punch stopped on an error: %s" % metrics.get("error", "see the error above"))
				return
			_rows.append(row)
			_pending -= 1)
		controllers.append(controller)
	_next += count
	_pending = count
	for controller in controllers:
		if not controller.call("punch"):
			_fail("PunchController refused to punch (see the error above)")
			return


func _fail(message: String) -> void:
	printerr("error: sized_hits: ", message)
	_failed = true
	quit(2)
