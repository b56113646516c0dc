# Cura post-processing script: runs poa (Print on Air) on the G-code Cura just sliced.
#
# Install: copy this file into Cura's `scripts` folder (Help -> Show Configuration Folder,
# then `scripts/`; create it if needed), restart Cura, then Extensions -> Post Processing ->
# Modify G-Code -> Add a script -> "Print on Air (poa)". Set the path of the poa binary.
#
# What it does: writes the sliced G-code to a temporary file, runs
# `poa [--profile P] [extra options] FILE` on it (the same slicer mode PrusaSlicer uses), and
# hands the rewritten G-code back to Cura. If poa fails, Cura gets the G-code unchanged and
# shows poa's message.

import json
import os
import subprocess
import tempfile

from ..Script import Script

try:
    from UM.Logger import Logger
    from UM.Message import Message
except ImportError:  # outside Cura
    Logger = None
    Message = None


def _log(level, text):
    if Logger is not None:
        Logger.log(level, text)


def _tell_user(text):
    if Message is not None:
        Message(text, title="Print on Air (poa)").show()


def _cura_setting(key):
    """A setting of the active machine/extruder, or None outside Cura."""
    try:
        from cura.CuraApplication import CuraApplication

        stack = CuraApplication.getInstance().getGlobalContainerStack()
        extruders = stack.extruderList if stack is not None else []
        target = extruders[0] if extruders else stack
        return target.getProperty(key, "value")
    except Exception:  # noqa: BLE001 - any failure means "not available"
        return None


class PoaPrintOnAir(Script):
    def getSettingDataString(self):
        return json.dumps(
            {
                "name": "Print on Air (poa)",
                "key": "PoaPrintOnAir",
                "metadata": {},
                "version": 2,
                "settings": {
                    "poa_path": {
                        "label": "poa program",
                        "description": "Full path of the poa binary (or just 'poa' if it is on the PATH).",
                        "type": "str",
                        "default_value": "poa",
                    },
                    "profile": {
                        "label": "Profile",
                        "description": "Built-in profile (pla, petg, abs, tpu) or path of a YAML profile. Empty: poa's defaults.",
                        "type": "str",
                        "default_value": "",
                    },
                    "bridges": {
                        "label": "Rewrite bridges too",
                        "description": "Also rewrite regions anchored on two sides (bridges).",
                        "type": "bool",
                        "default_value": False,
                    },
                    "extra": {
                        "label": "Extra options",
                        "description": "More poa options, e.g. --fan 80 --set dwell=0.5",
                        "type": "str",
                        "default_value": "",
                    },
                },
            }
        )

    def command(self, path):
        """The command line poa is run with (a list, no shell)."""
        cmd = [self.getSettingValueByKey("poa_path") or "poa"]
        profile = (self.getSettingValueByKey("profile") or "").strip()
        if profile:
            cmd += ["--profile", profile]
        if self.getSettingValueByKey("bridges"):
            cmd += ["--bridges", "poa"]
        extra = (self.getSettingValueByKey("extra") or "").split()
        cmd += extra
        cmd.append(path)
        return cmd

    def execute(self, data):
        text = "".join(data)
        fd, path = tempfile.mkstemp(suffix=".gcode", prefix="poa-cura-")
        try:
            with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
                f.write(text)
            env = dict(os.environ)
            # Cura's G-code does not state the filament diameter; poa's flow model needs it.
            diameter = _cura_setting("material_diameter")
            if diameter:
                env["SLIC3R_FILAMENT_DIAMETER"] = str(diameter)
            cmd = self.command(path)
            try:
                result = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
            except (OSError, subprocess.TimeoutExpired) as e:
                message = "could not run {}: {}".format(cmd[0], e)
                _log("e", "poa: " + message)
                _tell_user("poa did not run: {}. The G-code was left as Cura sliced it.".format(message))
                return data
            if result.returncode != 0:
                message = (result.stderr or result.stdout or "exit code {}".format(result.returncode)).strip()
                _log("e", "poa failed: " + message)
                _tell_user("{} The G-code was left as Cura sliced it.".format(message))
                return data
            with open(path, "r", encoding="utf-8", newline="") as f:
                rewritten = f.read()
        finally:
            try:
                os.remove(path)
            except OSError:
                pass
        return split_layers(rewritten)


def split_layers(text):
    """Cura passes G-code as a list of layer chunks; keep that shape (a chunk starts at ;LAYER:)."""
    chunks = []
    current = []
    for line in text.splitlines(keepends=True):
        if line.startswith(";LAYER:") and current:
            chunks.append("".join(current))
            current = []
        current.append(line)
    if current:
        chunks.append("".join(current))
    return chunks
