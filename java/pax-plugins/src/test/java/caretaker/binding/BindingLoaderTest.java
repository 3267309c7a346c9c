package caretaker.binding;

import static org.junit.jupiter.api.Assertions.assertEquals;
import static org.junit.jupiter.api.Assertions.assertInstanceOf;
import static org.junit.jupiter.api.Assertions.assertNotNull;
import static org.junit.jupiter.api.Assertions.assertNull;
import static org.junit.jupiter.api.Assertions.assertThrows;

import caretaker.Repo;
import caretaker.rosbridge.LinkOptions;
import caretaker.rosbridge.RosAuth;
import caretaker.rosbridge.TestCerts;
import java.io.IOException;
import java.nio.file.Files;
import java.nio.file.Path;
import java.time.Duration;
import org.junit.jupiter.api.Test;
import org.junit.jupiter.api.io.TempDir;

/** The binding's link and security sections: values, defaults, paths relative to the file, errors with lines. */
class BindingLoaderTest {
    private static final String HEAD = "robot: r\nrosbridge: wss://127.0.0.1:9090\n";
    private static final String SYSTEMS = "systems:\n- sysrep: " + Repo.path("sysrep/cdra.yaml")
            + "\n  plugins: [ros_convention]\n  namespace: /cdra\n";

    private static Binding load(Path dir, String middle) throws IOException {
        return BindingLoader.load(Files.writeString(dir.resolve("b.yaml"), HEAD + middle + SYSTEMS), null);
    }

    private static String error(Path dir, String middle) {
        return assertThrows(BindingException.class, () -> load(dir, middle)).getMessage();
    }

    @Test
    void linkAndSecurityAreReadRelativeToTheFile(@TempDir Path dir) throws Exception {
        Path certs = Files.createDirectory(dir.resolve("certs"));
        TestCerts.make(certs);
        Files.writeString(dir.resolve("bridge.secret"), "  s3cret \n");
        Binding binding = load(dir, "link:\n  one_way_delay: 1.3\n  outage_budget: 90\nsecurity:\n"
                + "  ca_file: certs/ca.pem\n  secret_file: bridge.secret\n");
        assertEquals(new LinkOptions(Duration.ofMillis(1300), Duration.ofSeconds(90)), binding.link());
        RosAuth.Hmac auth = assertInstanceOf(RosAuth.Hmac.class, binding.auth());
        assertEquals("s3cret", auth.secret());
        assertEquals(Duration.ofMillis(61_300), auth.validity()); // a login arrives one delay old, then 60 s
        assertEquals(Duration.ofSeconds(120),
                new LinkOptions(Duration.ofSeconds(60), Duration.ofSeconds(1)).loginValidity());
        assertNotNull(binding.tls());
        assertEquals(binding.link().pingTimeout(), binding.rosOptions().pingTimeout());
        assertEquals(binding.auth(), binding.rosOptions().auth());

        Files.writeString(dir.resolve("bridge.token"), "tok\n");
        assertEquals(RosAuth.token("tok"), load(dir, "security: {token_file: bridge.token}\n").auth());
    }

    @Test
    void withoutTheSectionsTheLinkIsLoopbackAndNothingAuthenticates(@TempDir Path dir) throws IOException {
        Binding binding = load(dir, "");
        assertEquals(LinkOptions.loopback(), binding.link());
        assertNull(binding.auth());
        assertNull(binding.tls());
        assertEquals(LinkOptions.loopback(), BindingLoader.load(Repo.path("sysrep/bindings/iva.yaml"), null).link());
    }

    @Test
    void badValuesNameFileLineAndKey(@TempDir Path dir) throws IOException {
        String file = dir.resolve("b.yaml").toString();
        assertEquals(file + ":4: link.outage_budget: must be a positive number of seconds, got -1",
                error(dir, "link:\n  outage_budget: -1\n"));
        assertEquals(file + ":4: link.one_way_delay: must be a number of seconds (0 or more), got soon",
                error(dir, "link:\n  one_way_delay: soon\n"));
        assertEquals(file + ":5: link.delay: unknown key (allowed: one_way_delay, outage_budget)",
                error(dir, "link:\n  outage_budget: 5\n  delay: 1\n"));
        assertEquals(file + ":3: link: must be a mapping of one_way_delay, outage_budget", error(dir, "link: 5\n"));
        Files.writeString(dir.resolve("s"), "x");
        assertEquals(file + ":5: security.token_file: give secret_file (HMAC) or token_file (bearer token), not both",
                error(dir, "security:\n  secret_file: s\n  token_file: s\n"));
        assertEquals(file + ":4: security.secret_file: cannot read " + dir.resolve("missing") + " (NoSuchFileException)",
                error(dir, "security:\n  secret_file: missing\n"));
        Files.writeString(dir.resolve("empty"), "\n");
        assertEquals(file + ":4: security.secret_file: " + dir.resolve("empty")
                + " is empty; put the bridge's shared secret in it", error(dir, "security:\n  secret_file: empty\n"));
        String ca = error(dir, "security:\n  ca_file: s\n");
        assertEquals(file + ":4: security.ca_file: CA file " + dir.resolve("s") + " is not a PEM certificate",
                ca.substring(0, ca.indexOf(" certificate") + " certificate".length()));
        assertEquals(file + ":4: security.ca_file: must be a file path (relative to the binding), got 3",
                error(dir, "security:\n  ca_file: 3\n"));
    }
}
