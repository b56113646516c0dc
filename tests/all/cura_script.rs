//! The Cura post-processing script, run with a stub of Cura's Script API (Cura itself is not
//! installable here): it must call poa correctly, hand it Cura's settings as `SLIC3R_*`
//! variables and surface a failure to the user.

use crate::common;

use std::path::Path;
use std::process::Command;

use common::*;

/// `UM/Application.py`: `Application.getInstance().getGlobalContainerStack()` is built from
/// `UM/stack.json` (`{"global": {key: value}, "extruders": [{"values": {..}, "material":
/// {metadata}}]}`), None when that file is absent. A value `"__raise__"` makes `getProperty`
/// raise, as a broken setting would.
const APPLICATION: &str = r#"
import json, os

_STACK = os.path.join(os.path.dirname(os.path.abspath(__file__)), "stack.json")


class _Container:
    def __init__(self, metadata):
        self._metadata = metadata

    def getMetaDataEntry(self, key, default=None):
        return self._metadata.get(key, default)


class _Stack:
    def __init__(self, values, material=None):
        self._values = values
        self.material = _Container(material or {})

    def getProperty(self, key, prop):
        assert prop == "value", prop
        value = self._values.get(key)
        if value == "__raise__":
            raise RuntimeError("broken setting " + key)
        return value


class _GlobalStack(_Stack):
    def __init__(self, values, extruders):
        super().__init__(values)
        self.extruderList = [_Stack(e.get("values", {}), e.get("material")) for e in extruders]


class Application:
    _instance = None

    @classmethod
    def getInstance(cls):
        if cls._instance is None:
            cls._instance = cls()
        return cls._instance

    def getGlobalContainerStack(self):
        if not os.path.exists(_STACK):
            return None
        with open(_STACK, encoding="utf-8") as f:
            d = json.load(f)
        return _GlobalStack(d.get("global", {}), d.get("extruders", []))
"#;

/// Lays out the packages the script expects (`..Script`, `UM.Logger`, `UM.Message`,
/// `UM.Application`), with Cura's machine settings `stack` (none: no active machine).
fn stub_cura(dir: &Path, stack: Option<&serde_json::Value>) {
    let plugin = dir.join("PostProcessingPlugin");
    std::fs::create_dir_all(plugin.join("scripts")).unwrap();
    std::fs::create_dir_all(dir.join("UM")).unwrap();
    std::fs::write(plugin.join("__init__.py"), "").unwrap();
    std::fs::write(plugin.join("scripts/__init__.py"), "").unwrap();
    std::fs::write(
        plugin.join("Script.py"),
        "class Script:\n    def __init__(self):\n        self.values = {}\n    \
         def getSettingValueByKey(self, key):\n        return self.values.get(key)\n",
    )
    .unwrap();
    std::fs::write(dir.join("UM/__init__.py"), "").unwrap();
    std::fs::write(
        dir.join("UM/Logger.py"),
        "class Logger:\n    lines = []\n    @classmethod\n    def log(cls, level, text):\n        cls.lines.append((level, text))\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("UM/Message.py"),
        "class Message:\n    shown = []\n    def __init__(self, text, title=None):\n        self.text = text\n    \
         def show(self):\n        Message.shown.append(self.text)\n",
    )
    .unwrap();
    std::fs::write(dir.join("UM/Application.py"), APPLICATION).unwrap();
    if let Some(stack) = stack {
        std::fs::write(dir.join("UM/stack.json"), stack.to_string()).unwrap();
    }
    std::fs::copy(
        repo().join("integrations/cura/PoaPrintOnAir.py"),
        plugin.join("scripts/PoaPrintOnAir.py"),
    )
    .unwrap();
}

const DRIVER: &str = r#"
import json, sys
from PostProcessingPlugin.scripts.PoaPrintOnAir import PoaPrintOnAir
from UM.Message import Message
settings = json.loads(sys.argv[1])
text = open(sys.argv[2], encoding="utf-8", newline="").read()
chunks = []
for line in text.splitlines(keepends=True):
    if line.startswith(";LAYER:") or not chunks:
        chunks.append("")
    chunks[-1] += line
s = PoaPrintOnAir()
json.loads(s.getSettingDataString())
s.values = settings
out = s.execute(chunks)
assert isinstance(out, list) and all(isinstance(c, str) for c in out)
open(sys.argv[3], "w", encoding="utf-8", newline="").write("".join(out))
print(json.dumps({"chunks_in": len(chunks), "chunks_out": len(out), "messages": Message.shown}))
"#;

fn run_script(settings: &str) -> (serde_json::Value, Vec<u8>, Vec<u8>) {
    run_script_with(settings, None, |_| {})
}

/// Runs the script with Cura's settings `stack`; `prepare` may alter the stub first.
fn run_script_with(
    settings: &str,
    stack: Option<&serde_json::Value>,
    prepare: impl FnOnce(&Path),
) -> (serde_json::Value, Vec<u8>, Vec<u8>) {
    let dir = tempfile::tempdir().unwrap();
    stub_cura(dir.path(), stack);
    prepare(dir.path());
    let input = sample("rect_overhang_cura.gcode");
    let out = dir.path().join("out.gcode");
    let mut cmd = Command::new("python3");
    // Only what the script passes may reach poa.
    for (k, _) in std::env::vars_os() {
        if k.to_string_lossy().starts_with("SLIC3R_") {
            cmd.env_remove(k);
        }
    }
    let o = cmd
        .current_dir(dir.path())
        .arg("-c")
        .arg(DRIVER)
        .arg(settings)
        .arg(&input)
        .arg(&out)
        .output()
        .expect("python3");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    (v, read(&input), read(&out))
}

#[test]
fn cura_script_runs_poa_and_keeps_the_layer_chunks() {
    let settings = serde_json::json!({
        "poa_path": env!("CARGO_BIN_EXE_poa"),
        "profile": "pla",
        "bridges": false,
        "extra": "--fan 90",
    });
    let (v, input, output) = run_script(&settings.to_string());
    let text = String::from_utf8_lossy(&output);
    assert_eq!(text.matches(";POA_BEGIN").count(), 1, "rewritten");
    assert!(text.contains("profile pla"), "profile passed");
    assert!(text.contains("fan=90"), "extra options passed");
    assert_eq!(v["chunks_in"], v["chunks_out"], "same layer chunks");
    assert!(v["messages"].as_array().unwrap().is_empty());
    assert!(output.len() > input.len());
}

#[test]
fn cura_script_reports_a_failure_and_keeps_the_gcode() {
    let settings = serde_json::json!({
        "poa_path": env!("CARGO_BIN_EXE_poa"),
        "profile": "no-such-profile",
        "bridges": false,
        "extra": "",
    });
    let (v, input, output) = run_script(&settings.to_string());
    assert_eq!(output, input, "G-code unchanged");
    let msgs = v["messages"].as_array().unwrap();
    assert_eq!(msgs.len(), 1);
    assert!(
        msgs[0]
            .as_str()
            .unwrap()
            .contains("no profile `no-such-profile`"),
        "{msgs:?}"
    );

    let missing = serde_json::json!({"poa_path": "/nonexistent/poa", "profile": "", "bridges": false, "extra": ""});
    let (v, input, output) = run_script(&missing.to_string());
    assert_eq!(output, input);
    assert!(v["messages"][0].as_str().unwrap().contains("could not run"));
}

/// A stand-in for poa that writes its environment to `env.txt` (next to it) and leaves the
/// G-code as it is.
#[cfg(unix)]
fn fake_poa(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    use std::os::unix::fs::PermissionsExt;
    let poa = dir.join("poa");
    let env = dir.join("env.txt");
    std::fs::write(
        &poa,
        format!("#!/bin/sh\nenv > '{}'\nexit 0\n", env.display()),
    )
    .unwrap();
    std::fs::set_permissions(&poa, std::fs::Permissions::from_mode(0o755)).unwrap();
    (poa, env)
}

/// The SLIC3R_* variables the fake poa saw, or None if it did not run.
#[cfg(unix)]
fn run_fake_poa(
    stack: Option<&serde_json::Value>,
    prepare: impl FnOnce(&Path),
) -> Option<std::collections::BTreeMap<String, String>> {
    let bin = tempfile::tempdir().unwrap();
    let (poa, env) = fake_poa(bin.path());
    let settings = serde_json::json!({
        "poa_path": poa.to_str().unwrap(),
        "profile": "",
        "bridges": false,
        "extra": "",
    });
    let (v, input, output) = run_script_with(&settings.to_string(), stack, prepare);
    assert!(v["messages"].as_array().unwrap().is_empty(), "{v}");
    assert_eq!(output, input, "the fake poa leaves the G-code as it is");
    assert_eq!(v["chunks_in"], v["chunks_out"]);
    let text = std::fs::read_to_string(env).ok()?;
    Some(
        text.lines()
            .filter_map(|l| l.split_once('='))
            .filter(|(k, _)| k.starts_with("SLIC3R_"))
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect(),
    )
}

#[cfg(unix)]
#[test]
fn cura_script_passes_curas_settings_as_slic3r_variables() {
    let stack = serde_json::json!({
        "global": {
            "layer_height": 0.2,
            "machine_nozzle_size": 0.6,
            "speed_travel": 200,
        },
        "extruders": [{
            "values": {
                "material_type": "PETG",
                "bridge_wall_speed": 17,
                "bridge_skin_speed": 12,
                "wall_line_width_0": 0.42,
                "wall_line_width_x": 0.45,
                "line_width": 0.4,
                "machine_nozzle_size": 0.4,
                "material_diameter": 1.75,
                "retraction_enable": true,
                "retraction_amount": 0.8,
                "speed_travel": 180.0,
                "retraction_hop_enabled": true,
                "retraction_hop": 0.2,
            },
            "material": {"material": "PLA"},
        }],
    });
    let env = run_fake_poa(Some(&stack), |_| {}).expect("poa ran");
    let expected = [
        ("SLIC3R_FILAMENT_TYPE", "PETG"),
        ("SLIC3R_BRIDGE_SPEED", "17"),
        ("SLIC3R_EXTERNAL_PERIMETER_EXTRUSION_WIDTH", "0.42"),
        ("SLIC3R_PERIMETER_EXTRUSION_WIDTH", "0.45"),
        ("SLIC3R_EXTRUSION_WIDTH", "0.4"),
        // The extruder's value wins over the machine's.
        ("SLIC3R_NOZZLE_DIAMETER", "0.4"),
        ("SLIC3R_TRAVEL_SPEED", "180"),
        // Only the machine has it.
        ("SLIC3R_LAYER_HEIGHT", "0.2"),
        ("SLIC3R_FILAMENT_DIAMETER", "1.75"),
        ("SLIC3R_RETRACT_LENGTH", "0.8"),
        ("SLIC3R_RETRACT_LIFT", "0.2"),
    ];
    let want: std::collections::BTreeMap<String, String> = expected
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    assert_eq!(env, want);
}

#[cfg(unix)]
#[test]
fn cura_script_falls_back_and_skips_what_cura_lacks() {
    // No material_type setting (Cura keeps it in the material profile), no wall bridge speed,
    // no Z hop, retraction off, a setting that fails to read and one that is not a number.
    let stack = serde_json::json!({
        "global": {"layer_height": "__raise__"},
        "extruders": [{
            "values": {
                "bridge_skin_speed": 12.5,
                "wall_line_width_0": "__raise__",
                "line_width": "wide",
                "retraction_enable": false,
                "retraction_amount": 6.5,
                "retraction_hop_enabled": false,
                "retraction_hop": 0.4,
            },
            "material": {"material": "PLA"},
        }],
    });
    let env = run_fake_poa(Some(&stack), |_| {}).expect("poa ran");
    let got: Vec<(&str, &str)> = env.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
    assert_eq!(
        got,
        [
            ("SLIC3R_BRIDGE_SPEED", "12.5"),
            ("SLIC3R_FILAMENT_TYPE", "PLA"),
            ("SLIC3R_RETRACT_LENGTH", "0"),
        ]
    );
}

#[cfg(unix)]
#[test]
fn cura_script_runs_poa_without_curas_settings() {
    // No active machine.
    let env = run_fake_poa(None, |_| {}).expect("poa ran without a machine");
    assert!(env.is_empty(), "{env:?}");
    // No UM.Application at all (nor cura.CuraApplication).
    let stack = serde_json::json!({"global": {"layer_height": 0.2}, "extruders": []});
    let env = run_fake_poa(Some(&stack), |dir| {
        std::fs::remove_file(dir.join("UM/Application.py")).unwrap();
    })
    .expect("poa ran without UM.Application");
    assert!(env.is_empty(), "{env:?}");
    // A machine without extruder stacks: the global stack answers.
    let env = run_fake_poa(Some(&stack), |_| {}).expect("poa ran");
    assert_eq!(
        env.get("SLIC3R_LAYER_HEIGHT").map(String::as_str),
        Some("0.2")
    );
    assert_eq!(env.len(), 1, "{env:?}");
}
