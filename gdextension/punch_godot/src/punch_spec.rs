//! `PunchSpec`: what policies are trained with, for the game's scripts and the editor plugin (static
//! functions only; `punch_core::contract::spec` and `punch_core::contract::sensing` define it all).

use godot::builtin::{GString, PackedStringArray, VarDictionary, Vector3};
use godot::classes::{Engine, ProjectSettings};
use godot::meta::ToGodot;
use godot::obj::Singleton;
use godot::prelude::{GodotClass, godot_api};
use punch_core::contract::sensing::FEATURE_NAMES;
use punch_core::contract::spec::{EpisodeConditions, PROJECT_SETTINGS, SettingValue, project_setting_problems};

/// The policy contract as a game sees it: where training puts the target, the project settings policies
/// are trained with, and the names of the per-frame features. Static functions: `PunchSpec.default_target_offset()`.
#[derive(GodotClass)]
#[class(no_init, base = Object)]
pub struct PunchSpec {}

#[godot_api]
impl PunchSpec {
    /// Where the training puts the target's centre relative to the character's root, in the character's
    /// frame (+Z ahead, +Y up, +X the character's left), in metres: place a target here for the trained
    /// punch (`character.transform * PunchSpec.default_target_offset()`).
    #[func]
    fn default_target_offset() -> Vector3 {
        let position = EpisodeConditions::DEFAULT.position();
        Vector3::new(position.x, position.y, position.z)
    }

    /// The project settings policies are trained with (setting path to value): a game needs the same.
    #[func]
    fn required_project_settings() -> VarDictionary {
        let mut settings = VarDictionary::new();
        for setting in PROJECT_SETTINGS {
            let value = match setting.value {
                SettingValue::Int(v) => v.to_variant(),
                SettingValue::Float(v) => v.to_variant(),
                SettingValue::Text(v) => v.to_variant(),
            };
            settings.set(setting.path, &value);
        }
        settings
    }

    /// The running game's settings that differ from `required_project_settings()`, one line each saying
    /// what to set (empty when all is well). The physics rate is the engine's current one.
    #[func]
    pub fn project_settings_problems() -> PackedStringArray {
        project_setting_problems(|path| {
            if path == PROJECT_SETTINGS[0].path {
                return (Some(Engine::singleton().get_physics_ticks_per_second() as f64), None);
            }
            let value = ProjectSettings::singleton().get_setting(path);
            let number = value.try_to::<f64>().ok().or_else(|| value.try_to::<i64>().ok().map(|v| v as f64));
            (number, value.try_to::<GString>().ok().map(|s| s.to_string()))
        })
        .iter()
        .map(GString::from)
        .collect()
    }

    /// Names of the per-frame features (`PunchController.last_punch_record()`'s columns, the training
    /// server's features), in column order.
    #[func]
    fn feature_names() -> PackedStringArray {
        FEATURE_NAMES.iter().map(|name| GString::from(*name)).collect()
    }
}
