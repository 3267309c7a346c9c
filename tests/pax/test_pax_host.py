"""pride.pax_host without a robot: the JVM and classpath, value conversion both ways, Java
errors as PaxError, listeners. Tests that need a rosbridge server use the real one
(`caretaker bridge --port 0`) with no ROS services behind it."""

from __future__ import annotations

import logging
import queue
from pathlib import Path

import jpype
import pytest
from pax_stack import REPO

import pride.jvm
from pride.pax_host import PaxError, PaxHost, to_java, to_python
from pride.systems import CommandResult, TelemetryValue
from procedure_language.sysrep import SysRepError, load_sysrep
from support.stack import robot_parts

AT_SYSREP = REPO / "sysrep" / "affordance_templates.yaml"
CDRA_SYSREP = REPO / "sysrep" / "cdra.yaml"


@pytest.fixture(scope="module")
def url(ros_env_module: dict[str, str]) -> str:
    with robot_parts("iva", ros_env_module, parts=("bridge",)) as bridge:
        yield bridge.bridge_url


def write_binding(directory: Path, body: str) -> Path:
    path = directory / "binding.yaml"
    path.write_text(body)
    return path


def binding_text(stale_after: float = 1.0) -> str:
    return (
        f"robot: test\nrosbridge: ws://127.0.0.1:9\nsystems:\n"
        f"- sysrep: {AT_SYSREP}\n  plugins: [at_commands, at_telemetry]\n"
        f"  namespace: /affordance_template_server\n  options: {{stale_after: {stale_after}, call_timeout: 5}}\n"
        f"- sysrep: {CDRA_SYSREP}\n  plugins: [ros_convention]\n  namespace: /cdra\n  options: {{call_timeout: 5}}\n"
    )


def test_missing_jar_says_how_to_build_it(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setattr(pride.jvm, "PLUGIN_JAR", tmp_path / "pax-plugins.jar")
    with pytest.raises(pride.jvm.JarNotBuiltError, match="make setup"):
        pride.jvm.classpath()


def test_classpath_is_the_jar_and_debian_jars() -> None:
    path = pride.jvm.classpath()
    assert path[0].endswith("java/pax-plugins/target/pax-plugins.jar")
    assert {Path(p).name for p in path[1:]} == {"gson.jar", "snakeyaml.jar"}


def test_values_convert_to_sysrep_java_types_and_back() -> None:
    pride.jvm.start_jvm()
    assert to_java("flag", True).getClass().getName() == "java.lang.Boolean"
    assert to_java("n", 3).getClass().getName() == "java.lang.Long"
    assert to_java("x", 2.5).getClass().getName() == "java.lang.Double"
    assert str(to_java("s", "text").getClass().getName()) == "java.lang.String"
    with pytest.raises(PaxError, match="argument 'pose'.*list"):
        to_java("pose", [1, 2])
    for python_value in (True, False, 7, -2.25, "ok"):
        back = to_python(to_java("v", python_value))
        assert back == python_value and type(back) is type(python_value)
    assert to_python(None) is None


def test_a_bad_sysrep_in_a_binding_reads_like_the_python_loader(tmp_path: Path) -> None:
    invalid = REPO / "tests/fixtures/sysrep/invalid/unknown_type.yaml"
    binding = write_binding(
        tmp_path, f"robot: t\nrosbridge: ws://127.0.0.1:9\nsystems:\n- sysrep: {invalid}\n  plugins: [ros_convention]\n"
    )
    with pytest.raises(PaxError) as java_error:
        PaxHost(binding)
    with pytest.raises(SysRepError) as python_error:
        load_sysrep(invalid)
    assert str(java_error.value) == str(python_error.value)
    assert java_error.value.java_class == "caretaker.sysrep.SysRepException"


def test_binding_mistakes_name_file_and_entry(tmp_path: Path) -> None:
    binding = write_binding(tmp_path, binding_text().replace("plugins: [ros_convention]", "plugins: [ros_conventions]"))
    with pytest.raises(PaxError, match=r"binding.yaml: systems\[1\]: unknown plugin 'ros_conventions'"):
        PaxHost(binding, rosbridge_url="ws://127.0.0.1:9")  # checked before any connection is tried
    binding = write_binding(tmp_path, binding_text().replace("namespace: /cdra", "namspace: /cdra"))
    with pytest.raises(PaxError, match=r"systems\[1\]: unknown key 'namspace'"):
        PaxHost(binding)


def test_unreachable_rosbridge_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(PaxError, match="caretaker bridge") as error:
        PaxHost(write_binding(tmp_path, binding_text()), rosbridge_url="ws://127.0.0.1:9")
    assert "ws://127.0.0.1:9" in str(error.value)


def test_commands_and_telemetry_without_a_robot(url: str, tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    host = PaxHost(write_binding(tmp_path, binding_text(stale_after=1.0)), rosbridge_url=url)
    try:
        assert host.system_ids() == {"affordance_templates", "cdra"}
        changes: queue.Queue[tuple[str, str, TelemetryValue]] = queue.Queue()

        def broken_listener(sysrep: str, item: str, value: TelemetryValue) -> None:
            raise RuntimeError("listener bug")

        host.add_listener(broken_listener)
        host.add_listener(lambda sysrep, item, value: changes.put((sysrep, item, value)))

        # No AT server: after stale_after the server reads inactive (a fresh false), the rest stale.
        # The bound is the suite's load, not the plugin: a starved JVM looks late (seen past 15 s).
        with caplog.at_level(logging.ERROR, logger="pride.pax_host"):
            sysrep, item, value = changes.get(timeout=90.0)
        assert (sysrep, item) == ("affordance_templates", "affordance_template_server_active")
        assert value.value is False and value.stale is False and isinstance(value.timestamp, float)
        assert host.telemetry("affordance_templates", "plan_status") == TelemetryValue(None, None, True)
        assert "listener bug" in caplog.text and "telemetry listener" in caplog.text

        # No service behind the bridge: a failed result with the bridge's reason, not an exception.
        result = host.execute("cdra", "unlock_filter", {})
        assert isinstance(result, CommandResult) and result.success is False
        assert "/cdra/unlock_filter" in result.message

        with pytest.raises(PaxError, match="missing argument 'trajectory'"):
            host.execute("affordance_templates", "plan_trajectory", {"affordance_template": "cdra_filter"})
        with pytest.raises(PaxError, match="id: expected integer, got 'zero'"):
            host.execute(
                "affordance_templates", "delete_affordance_template", {"affordance_template": "x", "id": "zero"}
            )
        with pytest.raises(PaxError, match="has no command 'open_hatch'"):
            host.execute("cdra", "open_hatch", {})
        with pytest.raises(PaxError, match="'eclss' is not bound"):
            host.telemetry("eclss", "pressure")
    finally:
        host.close()
        host.close()  # idempotent
    assert jpype.isJVMStarted()
