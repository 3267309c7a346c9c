package caretaker.binding;

import static org.junit.jupiter.api.Assertions.assertEquals;
import static org.junit.jupiter.api.Assertions.assertFalse;
import static org.junit.jupiter.api.Assertions.assertThrows;
import static org.junit.jupiter.api.Assertions.assertTrue;

import caretaker.Repo;
import java.io.IOException;
import java.nio.file.Files;
import java.nio.file.Path;
import java.util.List;
import java.util.Map;
import java.util.TreeSet;
import java.util.stream.Stream;
import org.junit.jupiter.api.DynamicTest;
import org.junit.jupiter.api.TestFactory;
import org.yaml.snakeyaml.Yaml;

/**
 * The Java loader against the binding fixtures the Python reader (procedure_language.binding) is tested with
 * (tests/fixtures/bindings): both accept the same files and refuse the same ones, saying the same.
 */
class BindingFixturesTest {
    private static final Path FIXTURES = Repo.path("tests/fixtures/bindings");

    private static List<Path> fixtures(String kind) throws IOException {
        try (Stream<Path> listing = Files.list(FIXTURES.resolve(kind))) {
            return listing.filter(p -> p.toString().endsWith(".yaml"))
                    .filter(p -> !p.getFileName().toString().equals("expected_errors.yaml")).sorted().toList();
        }
    }

    @TestFactory
    Stream<DynamicTest> everyValidFixtureLoads() throws IOException {
        List<Path> files = fixtures("valid");
        assertFalse(files.isEmpty(), "no valid fixtures in " + FIXTURES);
        return files.stream().map(file -> DynamicTest.dynamicTest(file.getFileName().toString(), () -> {
            Binding binding = BindingLoader.load(file, null);
            assertEquals("lab", binding.robot());
            assertFalse(binding.systems().isEmpty());
        }));
    }

    @TestFactory
    Stream<DynamicTest> everyInvalidFixtureFailsWithTheSharedMessage() throws IOException {
        Map<String, List<String>> expected;
        try (var reader = Files.newBufferedReader(FIXTURES.resolve("invalid/expected_errors.yaml"))) {
            expected = new Yaml().load(reader);
        }
        List<Path> files = fixtures("invalid");
        assertEquals(expected.keySet(), new TreeSet<>(files.stream().map(p -> p.getFileName().toString()).toList()),
                "every invalid fixture needs an entry in expected_errors.yaml and vice versa");
        return files.stream().map(file -> DynamicTest.dynamicTest(file.getFileName().toString(), () -> {
            BindingException error = assertThrows(BindingException.class, () -> BindingLoader.load(file, null));
            assertFalse(error.getMessage().contains("\n"), "one line: " + error.getMessage());
            for (String part : expected.get(file.getFileName().toString())) {
                assertTrue(error.getMessage().contains(part), "'" + part + "' not in: " + error.getMessage());
            }
        }));
    }
}
