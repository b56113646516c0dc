//! The Cura post-processing script, run with a stub of Cura's Script API (Cura itself is not
//! installable here): it must call poa correctly and surface a failure to the user.

mod common;

use std::path::Path;
use std::process::Command;

use common::*;

/// Lays out the packages the script expects (`..Script`, `UM.Logger`, `UM.Message`).
fn stub_cura(dir: &Path) {
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
    let dir = tempfile::tempdir().unwrap();
    stub_cura(dir.path());
    let input = sample("rect_overhang_cura.gcode");
    let out = dir.path().join("out.gcode");
    let o = Command::new("python3")
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
