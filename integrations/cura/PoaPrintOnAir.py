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
#
# Cura's G-code carries almost none of its settings, so the script reads them from Cura (the
# first extruder's stack, then the global stack) and hands them to poa as the `SLIC3R_*`
# environment variables PrusaSlicer exports to its post-processing scripts (see CURA_TO_SLIC3R).
# A setting Cura does not have, or that cannot be read, is simply not passed.

import json
import math
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


def _cura_stacks():
    """The stacks settings are read from: the first extruder's, then the global one; [] when
    Cura (or an active machine) is not available."""
    app = None
    try:
        from UM.Application import Application

        app = Application.getInstance()
    except Exception:  # noqa: BLE001 - any failure means "not available"
        app = None
    if app is None:
        try:
            from cura.CuraApplication import CuraApplication

            app = CuraApplication.getInstance()
        except Exception:  # noqa: BLE001
            return []
    try:
        stack = app.getGlobalContainerStack()
    except Exception:  # noqa: BLE001
        return []
    if stack is None:
        return []
    try:
        extruders = list(stack.extruderList or [])
    except Exception:  # noqa: BLE001
        extruders = []
    stacks = [extruders[0]] if extruders and extruders[0] is not None else []
    return stacks + [stack]


def _cura_setting(key, stacks=None):
    """A setting of the active extruder (or, failing that, of the machine), or None."""
    for stack in _cura_stacks() if stacks is None else stacks:
        try:
            value = stack.getProperty(key, "value")
        except Exception:  # noqa: BLE001
            continue
        if value is not None:
            return value
    return None


def _material_type(stacks):
    """PLA, PETG...: a `material_type` setting if Cura has one, else the `material` entry of the
    extruder's material profile metadata."""
    value = _text(_cura_setting("material_type", stacks))
    if value:
        return value
    for stack in stacks:
        try:
            value = _text(stack.material.getMetaDataEntry("material"))
        except Exception:  # noqa: BLE001
            continue
        if value and value.lower() != "empty":
            return value
    return None


def _text(value):
    if value is None or isinstance(value, bool):
        return None
    text = str(value).strip()
    return text or None


def _number(value, positive=False):
    """A finite number written plainly (17, 0.42; no exponent), or None."""
    if value is None or isinstance(value, bool):
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None
    if not math.isfinite(x) or (positive and x <= 0):
        return None
    text = ("%.6f" % x).rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def _enabled(value):
    """Cura booleans (True/False, sometimes "True"/"False" strings); None when unknown."""
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.strip().lower() in ("true", "false"):
        return value.strip().lower() == "true"
    return None


# Cura setting (alternatives in order) -> poa's setting (PrusaSlicer spelling, SLIC3R_<KEY>).
# All are positive quantities: a zero or negative value is not passed.
CURA_TO_SLIC3R = [
    (("bridge_wall_speed", "bridge_skin_speed"), "bridge_speed"),
    (("wall_line_width_0",), "external_perimeter_extrusion_width"),
    (("wall_line_width_x",), "perimeter_extrusion_width"),
    (("line_width",), "extrusion_width"),
    (("machine_nozzle_size",), "nozzle_diameter"),
    (("layer_height",), "layer_height"),
    (("material_diameter",), "filament_diameter"),
    (("speed_travel",), "travel_speed"),
]


def slicer_env(stacks=None):
    """The SLIC3R_* variables for poa from Cura's settings ({} outside Cura). Never raises."""
    env = {}
    try:
        stacks = _cura_stacks() if stacks is None else stacks
        if not stacks:
            return env

        def put(key, value):
            if value is not None:
                env["SLIC3R_" + key.upper()] = value

        put("filament_type", _material_type(stacks))
        for cura_keys, key in CURA_TO_SLIC3R:
            for cura_key in cura_keys:
                value = _number(_cura_setting(cura_key, stacks), positive=True)
                if value is not None:
                    put(key, value)
                    break
        retracting = _enabled(_cura_setting("retraction_enable", stacks))
        if retracting is False:
            put("retract_length", "0")
        else:
            put("retract_length", _number(_cura_setting("retraction_amount", stacks)))
            if _enabled(_cura_setting("retraction_hop_enabled", stacks)):
                put("retract_lift", _number(_cura_setting("retraction_hop", stacks)))
    except Exception as e:  # noqa: BLE001 - settings are a help, never a reason to fail
        _log("w", "poa: could not read all of Cura's settings: {}".format(e))
    return env


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
            # Cura's G-code states hardly any of its settings (filament diameter, line widths,
            # bridge speed, material...); poa reads them from SLIC3R_* variables.
            settings = slicer_env()
            env.update(settings)
            if settings:
                passed = ", ".join("{}={}".format(k, v) for k, v in sorted(settings.items()))
                _log("d", "poa: Cura settings passed: " + passed)
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
