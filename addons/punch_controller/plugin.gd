@tool
extends EditorPlugin
## The addon's editor side (the node classes themselves come from the GDExtension and are always there):
## Project > Tools > "Add Punching Character" adds a character, a sandbag in front of it and a
## PunchController wired to both (with the addon's default straight-punch policy) to the open
## 3D scene, as one undoable action; Project > Tools > "Make Selected Skeleton Punch" does the same for a game's own
## rigged character (`own_character_setup.gd`: the selected Skeleton3D gets a PunchSkeletonModifier showing a
## simulated character that a PunchController drives at a sandbag).

const MENU_ITEM := "Add Punching Character"
const CHARACTER_SCENE := "res://addons/punch_controller/scenes/punch_character.tscn"
const SANDBAG_SCENE := "res://addons/punch_controller/scenes/punch_sandbag.tscn"
const DEFAULT_POLICY := "res://addons/punch_controller/policies/straight.onnx"
const SETTINGS_ITEM := "Apply Punch Physics Settings"
const SKELETON_ITEM := "Make Selected Skeleton Punch"
const PhysicsSettings := preload("res://addons/punch_controller/physics_settings.gd")
const OwnCharacterSetup := preload("res://addons/punch_controller/own_character_setup.gd")


func _enter_tree() -> void:
	if not ClassDB.class_exists("PunchController"):
		var platform := "%s %s" % [OS.get_name(), Engine.get_architecture_name()]
		if platform not in ["Linux x86_64", "Windows x86_64"]:
			push_error("Punch Controller: this addon has libraries for Linux x86_64 and Windows x86_64 only, so "
				+ "it does not run on " + platform + " (see the README, 'Platforms').")
		else:
			push_error("Punch Controller: the GDExtension is not loaded. Build it (scons, see the project's "
				+ "README) so that addons/punch_controller/bin/ has the library, then restart the editor.")
	add_tool_menu_item(MENU_ITEM, add_punching_character)
	add_tool_menu_item(SKELETON_ITEM, make_selected_skeleton_punch)
	add_tool_menu_item(SETTINGS_ITEM, offer_physics_settings)
	# `godot --editor SCENE -- --punch-select=NODE_PATH` opens with that node in the inspector (for docs).
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--punch-select="):
			_select_later.call_deferred(NodePath(argument.trim_prefix("--punch-select=")))


func _exit_tree() -> void:
	remove_tool_menu_item(MENU_ITEM)
	remove_tool_menu_item(SKELETON_ITEM)
	remove_tool_menu_item(SETTINGS_ITEM)


func _enable_plugin() -> void:
	offer_physics_settings.call_deferred()


## Asks to set the physics settings the policies need, when the project's differ (see the README).
func offer_physics_settings() -> void:
	if not ClassDB.class_exists("PunchController"):
		return
	var problems := PhysicsSettings.problems()
	if problems.is_empty():
		print("Punch Controller: the project's physics settings are the policies' already.")
		return
	var dialog := ConfirmationDialog.new()
	dialog.title = "Punch Controller: physics settings"
	dialog.dialog_text = ("Punching policies play as trained only with the physics settings they were trained "
		+ "with. This project differs:\n\n- " + "\n- ".join(problems)
		+ "\n\nSet them now? (A change of physics engine applies after restarting the editor.)")
	dialog.ok_button_text = "Set them"
	dialog.confirmed.connect(func():
		var changed := PhysicsSettings.apply()
		print("Punch Controller: set ", ", ".join(changed), "; restart the editor if the physics engine changed."))
	dialog.visibility_changed.connect(func(): if not dialog.visible: dialog.queue_free())
	EditorInterface.get_base_control().add_child(dialog)
	dialog.popup_centered()


## Adds the character, the sandbag and a wired PunchController under the edited scene's root.
func add_punching_character() -> void:
	var root := EditorInterface.get_edited_scene_root()
	if not root is Node3D:
		push_warning("Punch Controller: open a 3D scene first (its root must be a Node3D).")
		return
	var character: Node3D = load(CHARACTER_SCENE).instantiate()
	var sandbag: Node3D = load(SANDBAG_SCENE).instantiate()
	# Where the policies train the bag's centre to be, relative to the character (the spec's default).
	sandbag.position = ClassDB.class_call_static("PunchSpec", "default_target_offset")
	var controller: Node = ClassDB.instantiate("PunchController")
	controller.name = "PunchController"
	if ResourceLoader.exists(DEFAULT_POLICY) or FileAccess.file_exists(DEFAULT_POLICY):
		controller.set("policy", load(DEFAULT_POLICY))
	var undo := get_undo_redo()
	undo.create_action("Add Punching Character")
	for node in [character, sandbag, controller]:
		undo.add_do_method(root, "add_child", node, true)
		undo.add_do_property(node, "owner", root)
		undo.add_do_reference(node)
		undo.add_undo_method(root, "remove_child", node)
	undo.add_do_property(controller, "character", character)
	undo.add_do_property(controller, "target", sandbag.get_node("Bag"))
	undo.commit_action()
	EditorInterface.get_selection().clear()
	EditorInterface.get_selection().add_node(controller)


## Makes the selected Skeleton3D (or the scene's only one) punch: a PunchSkeletonModifier under it, the simulated
## character on the rig, a sandbag in front and a wired PunchController, as one undoable action (which turns on
## Editable Children for an instanced model, saying so in the Output). Says why in a dialog (and the Output) when
## there is no such skeleton or it lacks bones the modifier needs.
func make_selected_skeleton_punch() -> void:
	var root := EditorInterface.get_edited_scene_root()
	var skeleton := OwnCharacterSetup.find_skeleton(root, EditorInterface.get_selection().get_selected_nodes())
	var made := OwnCharacterSetup.make_skeleton_punch(root, skeleton, get_undo_redo())
	if not made.ok:
		push_warning("Punch Controller: " + made.message)
		var dialog := AcceptDialog.new()
		dialog.title = "Punch Controller: " + SKELETON_ITEM
		dialog.dialog_text = made.message
		dialog.dialog_autowrap = true
		dialog.min_size = Vector2i(520, 0)
		dialog.visibility_changed.connect(func(): if not dialog.visible: dialog.queue_free())
		EditorInterface.get_base_control().add_child(dialog)
		dialog.popup_centered()
		return
	for model in made.made_editable:
		# Without Editable Children the modifier under the model's Skeleton3D would not be saved with the scene.
		push_warning(("Punch Controller: turned on Editable Children for '%s' (an instanced model), so that the "
			+ "PunchSkeletonModifier under its Skeleton3D is saved with the scene. Keep it on; undo removes both.")
			% model.name)
	EditorInterface.get_selection().clear()
	EditorInterface.get_selection().add_node(made.controller)


func _select_later(path: NodePath, tries := 100) -> void:
	var root := EditorInterface.get_edited_scene_root()
	var node := root.get_node_or_null(path) if root else null
	if node:
		EditorInterface.edit_node(node)
		EditorInterface.get_selection().add_node(node)
	elif tries > 0:
		await get_tree().process_frame
		_select_later(path, tries - 1)
