package caretaker.rosbridge;

import static org.junit.jupiter.api.Assertions.assertEquals;
import static org.junit.jupiter.api.Assertions.assertFalse;
import static org.junit.jupiter.api.Assertions.assertNotEquals;
import static org.junit.jupiter.api.Assertions.assertThrows;
import static org.junit.jupiter.api.Assertions.assertTrue;

import com.google.gson.JsonObject;
import java.io.IOException;
import java.net.URI;
import java.nio.file.Path;
import java.time.Duration;
import java.time.Instant;
import java.util.List;
import java.util.Set;
import java.util.concurrent.BlockingQueue;
import java.util.concurrent.LinkedBlockingQueue;
import java.util.concurrent.TimeUnit;
import org.junit.jupiter.api.BeforeAll;
import org.junit.jupiter.api.Test;
import org.junit.jupiter.api.io.TempDir;

/** Authentication (HMAC and token) on every (re)connect, its refusal, wss:// with a test CA, keepalive. */
class RosSecurityTest {
    private static final String SECRET = "s3cret-for-tests";
    private static final RosOptions FAST = new RosOptions(Duration.ofSeconds(5), Duration.ofMillis(50),
            Duration.ofMillis(200));
    private static TestCerts certs;

    @BeforeAll
    static void makeCertificates(@TempDir Path dir) throws Exception {
        certs = TestCerts.make(dir);
    }

    /** Answers every call_service (the connect-time check included) with a successful empty reply. */
    private static List<JsonObject> answerCalls(JsonObject message) {
        if (!"call_service".equals(message.get("op").getAsString())) {
            return List.of();
        }
        JsonObject reply = new JsonObject();
        reply.addProperty("op", "service_response");
        reply.add("id", message.get("id"));
        reply.add("service", message.get("service"));
        reply.add("values", new JsonObject());
        reply.addProperty("result", true);
        return List.of(reply);
    }

    @Test
    void hmacAuthComesFirstOnEveryConnectWithAFreshRand() throws Exception {
        try (TestServer server = new TestServer(); Ros ros = new Ros(server.uri(),
                FAST.withAuth(RosAuth.hmac(SECRET)))) {
            server.respond(RosSecurityTest::answerCalls);
            long before = Instant.now().getEpochSecond();
            ros.connect();
            JsonObject first = server.next();
            assertEquals("auth", first.get("op").getAsString());
            assertEquals(Set.of("op", "mac", "client", "dest", "rand", "t", "level", "end"), first.keySet());
            assertEquals("127.0.0.1", first.get("dest").getAsString());
            long t = first.get("t").getAsLong();
            assertTrue(t >= before && t <= Instant.now().getEpochSecond(), "t is the client's Unix time: " + t);
            assertEquals(t + 60, first.get("end").getAsLong());
            String text = first.get("client").getAsString() + first.get("dest").getAsString()
                    + first.get("rand").getAsString() + t + first.get("level").getAsString() + (t + 60);
            assertEquals(RosAuth.Hmac.mac(SECRET, text), first.get("mac").getAsString());
            assertEquals(64, first.get("mac").getAsString().length());
            // python: hmac.new(b"key", b"text", hashlib.sha256).hexdigest()
            assertEquals("f7bc83f430538424b13298e6aa6fb143ef4d59a14946175997479dbc2d1a3cd8",
                    RosAuth.Hmac.mac("key", "The quick brown fox jumps over the lazy dog"));
            assertEquals("call_service", server.next().get("op").getAsString(), "then the connect-time check");

            server.dropClient();
            server.awaitClient();
            JsonObject again = server.next();
            assertEquals("auth", again.get("op").getAsString(), "auth first after a reconnect too");
            assertNotEquals(first.get("rand"), again.get("rand"));
            assertFalse(RosAuth.hmac(SECRET).toString().contains(SECRET));
        }
    }

    @Test
    void tokenAuthSendsTheToken() throws Exception {
        try (TestServer server = new TestServer(); Ros ros = new Ros(server.uri(), FAST.withAuth(RosAuth.token("tok")))) {
            server.respond(RosSecurityTest::answerCalls);
            ros.connect();
            JsonObject auth = server.next();
            assertEquals(2, auth.size());
            assertEquals("tok", auth.get("token").getAsString());
            assertEquals("Token[hidden]", RosAuth.token("tok").toString());
        }
    }

    @Test
    void aRefusedAuthIsReportedAndNotRetried() throws Exception {
        try (TestServer server = new TestServer(); Ros ros = new Ros(server.uri(), FAST.withAuth(RosAuth.hmac("x")))) {
            server.respond(message -> {
                if ("auth".equals(message.get("op").getAsString())) {
                    try {
                        server.closeClient(1008, "authentication failed: wrong mac");
                    } catch (IOException e) {
                        throw new AssertionError(e);
                    }
                }
                return List.of();
            });
            RosAuthException refused = assertThrows(RosAuthException.class, ros::connect);
            assertTrue(refused.getMessage().contains("refused authentication (close 1008: authentication failed:"
                    + " wrong mac)"), refused.getMessage());
            assertFalse(ros.isConnected());
            assertThrows(RosAuthException.class, () -> ros.awaitConnected(Duration.ofSeconds(1)));
            assertEquals(1, server.handshakes(), "no reconnect after a refusal");
        }
    }

    @Test
    void aRefusalAfterAReconnectStopsReconnectingAndTellsHandlers() throws Exception {
        try (TestServer server = new TestServer(); Ros ros = new Ros(server.uri(), FAST.withAuth(RosAuth.hmac("x")))) {
            server.respond(RosSecurityTest::answerCalls);
            ros.connect();
            server.next("call_service");
            BlockingQueue<Throwable> errors = new LinkedBlockingQueue<>();
            ros.addRosHandler(new RosHandler() {
                @Override
                public void handleError(Throwable error) {
                    errors.add(error);
                }
            });
            server.respond(message -> {
                if ("auth".equals(message.get("op").getAsString())) {
                    try {
                        server.closeClient(1008, "authentication failed: replayed");
                    } catch (IOException e) {
                        throw new AssertionError(e);
                    }
                }
                return List.of();
            });
            server.dropClient();
            server.next("auth");
            Throwable error = errors.poll(10, TimeUnit.SECONDS);
            assertTrue(error instanceof RosAuthException, String.valueOf(error));
            assertThrows(RosAuthException.class, () -> ros.awaitConnected(Duration.ofSeconds(1)));
            int handshakes = server.handshakes();
            assertEquals(null, server.poll(Duration.ofMillis(500)), "nothing more is tried");
            assertEquals(handshakes, server.handshakes());
        }
    }

    @Test
    void wssTrustsTheBindingsCaAndVerifiesTheHost() throws Exception {
        try (TestServer server = new TestServer(certs.serverTls())) {
            server.respond(RosSecurityTest::answerCalls);
            try (Ros ros = new Ros(server.uri(), FAST.withTls(CaTrust.trusting(certs.caPem())))) {
                ros.connect();
                assertEquals("wss", ros.getUri().getScheme());
                new Service(ros, "/x", null).callServiceAndWait(new ServiceRequest(), Duration.ofSeconds(5));
            }
            try (Ros wrongCa = new Ros(server.uri(), FAST.withTls(CaTrust.trusting(certs.otherCaPem())))) {
                RosException refused = assertThrows(RosException.class, wrongCa::connect);
                assertTrue(refused.getMessage().contains("cannot connect"), refused.getMessage());
            }
            try (Ros noCa = new Ros(server.uri(), FAST)) {
                assertThrows(RosException.class, noCa::connect, "the JDK's default CAs do not know the test CA");
            }
            URI byName = URI.create("wss://localhost:" + server.port());
            try (Ros wrongHost = new Ros(byName, FAST.withTls(CaTrust.trusting(certs.caPem())))) {
                RosException mismatch = assertThrows(RosException.class, wrongHost::connect);
                assertTrue(mismatch.getMessage().toLowerCase().contains("localhost"), mismatch.getMessage());
            }
        }
    }

    @Test
    void aCaFileThatIsNoCertificateSaysSo(@TempDir Path dir) throws IOException {
        Path bogus = java.nio.file.Files.writeString(dir.resolve("ca.pem"), "not a certificate\n");
        IllegalArgumentException error = assertThrows(IllegalArgumentException.class, () -> CaTrust.trusting(bogus));
        assertTrue(error.getMessage().contains(bogus.toString()), error.getMessage());
        assertThrows(IllegalArgumentException.class, () -> CaTrust.trusting(dir.resolve("missing.pem")));
    }

    @Test
    void keepalivePingsAndASilentServerIsDroppedAndReconnected() throws Exception {
        RosOptions quick = new RosOptions(Duration.ofSeconds(5), Duration.ofMillis(50), Duration.ofMillis(200),
                Duration.ofMillis(100), Duration.ofMillis(600), null, null);
        try (TestServer server = new TestServer(); Ros ros = new Ros(server.uri(), quick)) {
            ros.connect();
            BlockingQueue<String> events = new LinkedBlockingQueue<>();
            ros.addRosHandler(new RosHandler() {
                @Override
                public void handleDisconnection() {
                    events.add("down");
                }

                @Override
                public void handleConnection() {
                    events.add("up");
                }
            });
            server.awaitClient();
            while (server.pings() < 8) {
                assertEquals(null, events.poll(100, TimeUnit.MILLISECONDS), "answered pings keep the connection");
            }
            server.answerPings(false);
            assertEquals("down", events.poll(10, TimeUnit.SECONDS));
            assertTrue(ros.lostSince() != null || ros.isConnected());
            server.answerPings(true);
            assertEquals("up", events.poll(10, TimeUnit.SECONDS));
            assertEquals(2, server.handshakes());
        }
    }

    @Test
    void aQuietServerIsSaidSoLongBeforeItIsDroppedAndHeardAgainWhenItAnswers() throws Exception {
        // pings every 100 ms, given up after 30 s: quiet after 3 unanswered pings
        RosOptions quick = new RosOptions(Duration.ofSeconds(5), Duration.ofMillis(50), Duration.ofMillis(200),
                Duration.ofMillis(100), Duration.ofSeconds(30), null, null);
        try (TestServer server = new TestServer(); Ros ros = new Ros(server.uri(), quick)) {
            ros.connect();
            BlockingQueue<String> events = new LinkedBlockingQueue<>();
            ros.addRosHandler(new RosHandler() {
                @Override
                public void handleDisconnection() {
                    events.add("down");
                }

                @Override
                public void handleQuiet(java.time.Instant since) {
                    events.add(since == null ? "heard again" : "quiet");
                }
            });
            server.awaitClient();
            while (server.pings() < 5) {
                assertEquals(null, events.poll(100, TimeUnit.MILLISECONDS), "answered pings: not quiet");
            }
            server.answerPings(false);
            assertEquals("quiet", events.poll(10, TimeUnit.SECONDS));
            assertTrue(ros.isConnected() && ros.quietSince() != null, "quiet, still connected, last heard known");
            server.answerPings(true);
            assertEquals("heard again", events.poll(10, TimeUnit.SECONDS));
            assertEquals(null, ros.quietSince());
            assertEquals(null, events.poll(300, TimeUnit.MILLISECONDS), "never dropped: it was quiet, not gone");
        }
    }

    @Test
    void linkOptionsKeepTheConnectionThroughAnOutageWithinTheBudget() {
        LinkOptions gateway = new LinkOptions(Duration.ofMillis(1300), Duration.ofSeconds(60));
        assertEquals(Duration.ofMillis(5200), gateway.pingInterval());
        assertTrue(gateway.pingTimeout().compareTo(Duration.ofSeconds(60).plus(gateway.roundTrip())) > 0);
        RosOptions options = RosOptions.defaults().withLink(gateway);
        assertEquals(gateway.pingTimeout(), options.pingTimeout());
        assertEquals(Duration.ofSeconds(10).plus(gateway.roundTrip().multipliedBy(4)), options.timeout());
        assertEquals(Duration.ofSeconds(5), LinkOptions.loopback().pingInterval());
        assertThrows(IllegalArgumentException.class, () -> new LinkOptions(Duration.ofSeconds(-1), Duration.ofSeconds(1)));
        assertThrows(IllegalArgumentException.class, () -> new LinkOptions(Duration.ZERO, Duration.ZERO));
    }
}
