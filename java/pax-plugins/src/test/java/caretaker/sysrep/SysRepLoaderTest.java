package caretaker.sysrep;

import static org.junit.jupiter.api.Assertions.assertEquals;
import static org.junit.jupiter.api.Assertions.assertFalse;
import static org.junit.jupiter.api.Assertions.assertNull;
import static org.junit.jupiter.api.Assertions.assertThrows;
import static org.junit.jupiter.api.Assertions.assertTrue;

import java.io.IOException;
import java.nio.file.Files;
import java.nio.file.Path;
import java.util.ArrayList;
import java.util.LinkedHashMap;
import java.util.List;
import java.util.Map;
import java.util.stream.Stream;
import org.junit.jupiter.api.DynamicTest;
import org.junit.jupiter.api.Test;
import org.junit.jupiter.api.TestFactory;
import org.yaml.snakeyaml.Yaml;

/**
 * The Java loader against the fixtures the Python loader is tested with
 * (tests/fixtures/sysrep): both must accept the same files and report the same errors.
 */
class SysRepLoaderTest {
    private static final Path FIXTURES = caretaker.Repo.path("tests/fixtures/sysrep");

    @TestFactory
    Stream<DynamicTest> everyValidFixtureLoads() throws IOException {
        List<Path> files;
        try (Stream<Path> listing = Files.list(FIXTURES.resolve("valid"))) {
            files = listing.filter(p -> p.toString().endsWith(".yaml")).sorted().toList();
        }
        assertFalse(files.isEmpty(), "no valid fixtures found in " + FIXTURES);
        return files.stream().map(file -> DynamicTest.dynamicTest(file.getFileName().toString(), () -> {
            SysRep sysRep = SysRepLoader.load(file);
            assertFalse(sysRep.id().isEmpty());
        }));
    }

    @TestFactory
    Stream<DynamicTest> everyInvalidFixtureFailsWithTheSharedMessage() throws IOException {
        Map<String, List<String>> expected;
        try (var reader = Files.newBufferedReader(FIXTURES.resolve("invalid/expected_errors.yaml"))) {
            expected = new Yaml().load(reader);
        }
        List<Path> files;
        try (Stream<Path> listing = Files.list(FIXTURES.resolve("invalid"))) {
            files = listing.filter(p -> p.toString().endsWith(".yaml"))
                    .filter(p -> !p.getFileName().toString().equals("expected_errors.yaml")).sorted().toList();
        }
        assertEquals(expected.keySet(), new java.util.TreeSet<>(files.stream().map(p -> p.getFileName().toString())
                .toList()), "every invalid fixture needs an entry in expected_errors.yaml and vice versa");
        return files.stream().map(file -> DynamicTest.dynamicTest(file.getFileName().toString(), () -> {
            SysRepException error = assertThrows(SysRepException.class, () -> SysRepLoader.load(file));
            assertFalse(error.getMessage().contains("\n"), "one line: " + error.getMessage());
            for (String part : expected.get(file.getFileName().toString())) {
                assertTrue(error.getMessage().contains(part), "'" + part + "' not in: " + error.getMessage());
            }
        }));
    }

    @Test
    void figureOneLoadsVerbatim() {
        SysRep sysRep = SysRepLoader.load(caretaker.Repo.path("sysrep/affordance_templates.yaml"));
        assertEquals("affordance_templates", sysRep.id());
        assertEquals(List.of("add_affordance_template", "delete_affordance_template", "plan_trajectory",
                "execute_plan", "set_waypoint_pose", "set_display_object_pose"),
                sysRep.commands().stream().map(Command::id).toList());
        assertEquals(12, sysRep.command("set_waypoint_pose").args().size());
        assertEquals(ValueType.REAL, sysRep.command("set_display_object_pose").arg("yaw").type());
        assertEquals(List.of("robot_active", "planner_node_active", "affordance_template_server_active",
                "execute_status", "plan_status", "plan_valid"), sysRep.telemetry().stream().map(Telemetry::id).toList());
        assertEquals(6, sysRep.command("add_affordance_template").line(), "the same line procedure_language.sysrep reports");
    }

    @Test
    void everyShippedSysRepLoads() {
        Map<String, SysRep> all = SysRepLoader.loadDirectory(caretaker.Repo.path("sysrep"));
        assertTrue(all.keySet().containsAll(List.of("affordance_templates", "cdra", "camera")), all.keySet().toString());
    }

    @Test
    void extensionsAreRead() {
        SysRep sysRep = SysRepLoader.load(FIXTURES.resolve("valid/extensions.yaml"));
        Command move = sysRep.command("move_to");
        assertTrue(move.hazardous());
        assertEquals("m", move.arg("x").units());
        assertEquals(-2.0, move.arg("x").min().doubleValue());
        assertEquals(List.of("fast", "slow"), move.arg("mode").allowed());
        assertEquals("1.2", sysRep.version());
        assertNull(sysRep.command("nope"));
        Telemetry force = sysRep.telemetry().stream().filter(t -> t.id().equals("force")).findFirst().orElseThrow();
        assertEquals(new Limits(null, null, 30.0, 40.0, null, 1, 2.0), force.limits());
        Telemetry grasped = sysRep.telemetry().stream().filter(t -> t.id().equals("grasped")).findFirst().orElseThrow();
        assertEquals(new Limits(null, null, null, null, true, 3, 0.0), grasped.limits());
    }

    @Test
    void missingFileSaysSo() {
        SysRepException error = assertThrows(SysRepException.class, () -> SysRepLoader.load(Path.of("no/such.yaml")));
        assertTrue(error.getMessage().contains("no/such.yaml: cannot read"), error.getMessage());
    }

    @Test
    void argumentsAreCheckedAndConvertedLikePython() {
        SysRep sysRep = SysRepLoader.load(FIXTURES.resolve("valid/extensions.yaml"));
        Command move = sysRep.command("move_to");
        Map<String, Object> raw = new LinkedHashMap<>();
        raw.put("x", "1.5");
        raw.put("mode", "fast");
        assertEquals(Map.of("x", 1.5, "mode", "fast"), move.checkArguments(raw));
        raw.put("x", 3);
        IllegalArgumentException above = assertThrows(IllegalArgumentException.class, () -> move.checkArguments(raw));
        assertTrue(above.getMessage().contains("x: 3.0 is above the maximum 2.0"), above.getMessage());
        raw.put("x", 1.0);
        raw.put("mode", "medium");
        IllegalArgumentException notOne = assertThrows(IllegalArgumentException.class, () -> move.checkArguments(raw));
        assertTrue(notOne.getMessage().contains("mode: 'medium' is not one of ['fast', 'slow']"), notOne.getMessage());
        raw.remove("mode");
        assertTrue(assertThrows(IllegalArgumentException.class, () -> move.checkArguments(raw)).getMessage()
                .contains("missing argument 'mode'"));
        raw.put("mode", "fast");
        raw.put("speed", 1);
        assertTrue(assertThrows(IllegalArgumentException.class, () -> move.checkArguments(raw)).getMessage()
                .contains("unknown argument 'speed'"));
    }

    @Test
    void valueTypesFollowThePythonRules() {
        assertEquals(3L, ValueType.INTEGER.check("n", "3"));
        assertEquals(3L, ValueType.INTEGER.check("n", 3.0));
        assertEquals("n: expected integer, got 3.5", assertThrows(IllegalArgumentException.class,
                () -> ValueType.INTEGER.check("n", 3.5)).getMessage());
        assertEquals("n: expected integer, got True", assertThrows(IllegalArgumentException.class,
                () -> ValueType.INTEGER.check("n", true)).getMessage());
        assertEquals(true, ValueType.BOOLEAN.check("b", " TRUE "));
        assertEquals("b: expected boolean (true/false), got 1", assertThrows(IllegalArgumentException.class,
                () -> ValueType.BOOLEAN.check("b", 1L)).getMessage());
        assertEquals(2.5, ValueType.REAL.check("r", "2.5"));
        assertEquals("r: expected real, got False", assertThrows(IllegalArgumentException.class,
                () -> ValueType.REAL.check("r", false)).getMessage());
        assertEquals("s: expected string, got int 4", assertThrows(IllegalArgumentException.class,
                () -> ValueType.STRING.check("s", 4L)).getMessage());
        List<Object> values = new ArrayList<>();
        values.add(null);
        assertEquals("s: expected string, got NoneType None", assertThrows(IllegalArgumentException.class,
                () -> ValueType.STRING.check("s", values.get(0))).getMessage());
    }
}
