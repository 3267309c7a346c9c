"""The one JVM of this process, started with the PAX plugin jar and the Debian jars it needs.

JPype can start a JVM once per process and never restart it, so every user of Java in
Caretaker goes through :func:`start_jvm`, which starts it on first use and afterwards only checks
that the running JVM can see the plugins. The classpath is stated here and nowhere else.
"""

from __future__ import annotations

import logging
import threading
from pathlib import Path

import jpype

__all__ = ["JarNotBuiltError", "PLUGIN_JAR", "RUNTIME_JARS", "classpath", "start_jvm"]

_LOG = logging.getLogger(__name__)

REPO_ROOT = Path(__file__).resolve().parents[2]

#: Built by ``make setup`` (tools/setup.sh runs ``mvn -q package -DskipTests``).
PLUGIN_JAR = REPO_ROOT / "java" / "pax-plugins" / "target" / "pax-plugins.jar"

#: The plugins' runtime dependencies, from Debian (libgoogle-gson-java, libyaml-snake-java): the
#: same versions the Maven build compiles against (pom.xml pins them to Debian's repository).
RUNTIME_JARS = (Path("/usr/share/java/gson.jar"), Path("/usr/share/java/snakeyaml.jar"))

#: C1 only, no C2: a process runs little Java (the plugins' JSON and WebSocket calls), so C2 spent
#: more CPU compiling than its faster code gave back. A ``caretaker run`` of the IVA procedure
#: used 5.2-5.8 CPU-s with both compilers and 3.3-4.1 with C1 only (docs/benchmarks.md).
JVM_OPTIONS = ("-XX:TieredStopAtLevel=1",)

_start_lock = threading.Lock()


class JarNotBuiltError(RuntimeError):
    """A jar the plugins need is missing; the message says how to get it."""


def classpath() -> list[str]:
    """The JVM classpath for the PAX plugins.

    Raises:
        JarNotBuiltError: the plugin jar is not built, or a Debian jar is not installed.
    """
    if not PLUGIN_JAR.is_file():
        raise JarNotBuiltError(
            f"the PAX plugin jar {PLUGIN_JAR} is not built: run `make setup` "
            "(or `mvn -q package -DskipTests` in the repository root)"
        )
    for jar in RUNTIME_JARS:
        if not jar.is_file():
            raise JarNotBuiltError(
                f"{jar} is missing: run `make setup` (it installs libgoogle-gson-java and libyaml-snake-java)"
            )
    return [str(PLUGIN_JAR), *map(str, RUNTIME_JARS)]


def start_jvm() -> None:
    """Start the JVM with the plugin classpath, once per process; later calls only check it.

    Raises:
        JarNotBuiltError: a jar is missing, or a JVM started elsewhere cannot see the plugins.
    """
    with _start_lock:
        if not jpype.isJVMStarted():
            path = classpath()
            _LOG.info("starting the JVM with %s", ":".join(path))
            # convertStrings=False: Java strings stay Java objects until converted on purpose,
            # the behaviour JPype recommends and that a later JPype default change cannot alter.
            jpype.startJVM(*JVM_OPTIONS, classpath=path, convertStrings=False)
        try:
            jpype.JClass("caretaker.binding.PaxHost")
        except TypeError as exc:  # JPype raises TypeError for a class it cannot find
            raise JarNotBuiltError(
                f"a JVM is already running in this process without the PAX plugins on its classpath "
                f"({exc}); start it through pride.jvm.start_jvm() before any other Java use"
            ) from None
