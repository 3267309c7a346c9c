package caretaker.rosbridge;

import static org.junit.jupiter.api.Assertions.assertEquals;
import static org.junit.jupiter.api.Assertions.assertFalse;
import static org.junit.jupiter.api.Assertions.assertNotNull;
import static org.junit.jupiter.api.Assertions.assertNull;
import static org.junit.jupiter.api.Assertions.assertThrows;
import static org.junit.jupiter.api.Assertions.assertTrue;

import com.google.gson.JsonObject;
import com.google.gson.JsonParser;
import java.io.IOException;
import java.net.ServerSocket;
import java.net.URI;
import java.time.Duration;
import java.util.ArrayList;
import java.util.Collections;
import java.util.List;
import java.util.concurrent.BlockingQueue;
import java.util.concurrent.CompletableFuture;
import java.util.concurrent.CountDownLatch;
import java.util.concurrent.LinkedBlockingQueue;
import java.util.concurrent.TimeUnit;
import java.util.concurrent.TimeoutException;
import org.junit.jupiter.api.AfterEach;
import org.junit.jupiter.api.BeforeEach;
import org.junit.jupiter.api.Test;

/** The client's JSON shapes, ids, timeouts, failures, reconnects and fragments, against {@link TestServer}. */
class RosTest {
    private static final RosOptions FAST = new RosOptions(Duration.ofSeconds(5), Duration.ofMillis(50),
            Duration.ofMillis(200));

    private TestServer server;
    private Ros ros;

    @BeforeEach
    void start() throws Exception {
        server = new TestServer();
        ros = new Ros(server.uri(), FAST);
        ros.connect();
        server.awaitClient();
    }

    @AfterEach
    void stop() throws IOException {
        ros.close();
        server.close();
    }

    private static JsonObject json(String text) {
        return JsonParser.parseString(text).getAsJsonObject();
    }

    private static JsonObject reply(JsonObject call, String values, boolean result) {
        return json("{\"op\":\"service_response\",\"service\":" + call.get("service") + ",\"id\":" + call.get("id")
                + ",\"values\":" + values + ",\"result\":" + result + "}");
    }

    @Test
    void connectsAndDisconnects() {
        assertTrue(ros.isConnected());
        assertEquals(server.uri(), ros.getUri());
        ros.disconnect();
        assertFalse(ros.isConnected());
    }

    @Test
    void connectingToNothingSaysWhere() throws IOException {
        int port;
        try (ServerSocket free = new ServerSocket(0)) {
            port = free.getLocalPort();
        }
        try (Ros nowhere = new Ros(URI.create("ws://127.0.0.1:" + port), FAST)) {
            RosException error = assertThrows(RosException.class, nowhere::connect);
            assertTrue(error.getMessage().contains("ws://127.0.0.1:" + port), error.getMessage());
            assertFalse(nowhere.isConnected());
        }
    }

    @Test
    void aSlowServerIsTriedAgainWithinThePatienceAndATimeoutPastItIsReported() throws Exception {
        RosOptions quick = new RosOptions(Duration.ofMillis(300), Duration.ofMillis(50), Duration.ofMillis(200));
        try (TestServer slow = new TestServer(); Ros patient = new Ros(slow.uri(), quick)) {
            slow.leaveHandshakesUnanswered(2); // two opening handshakes time out, the third is answered
            patient.connect(Duration.ofSeconds(30));
            assertTrue(patient.isConnected());
            assertEquals(1, slow.handshakes());
        }
        try (TestServer slow = new TestServer(); Ros impatient = new Ros(slow.uri(), quick)) {
            slow.leaveHandshakesUnanswered(100);
            RosTimeoutException error = assertThrows(RosTimeoutException.class,
                    () -> impatient.connect(Duration.ofMillis(500)));
            assertTrue(error.getMessage().contains("no answer within"), error.getMessage());
            assertFalse(impatient.isConnected());
        }
    }

    @Test
    void rejectsNonWebSocketUri() {
        assertThrows(IllegalArgumentException.class, () -> new Ros(URI.create("http://x:1"), FAST));
    }

    @Test
    void subscribeSendsJrosbridgeShapeAndDeliversMessages() throws Exception {
        BlockingQueue<Message> messages = new LinkedBlockingQueue<>();
        Topic topic = new Topic(ros, "/chatter", "std_msgs/msg/String");
        topic.subscribe(messages::add);
        assertEquals(json("{\"op\":\"subscribe\",\"id\":\"subscribe:/chatter:0\",\"topic\":\"/chatter\","
                + "\"type\":\"std_msgs/msg/String\",\"compression\":\"none\",\"throttle_rate\":0,"
                + "\"queue_length\":0}"), server.next());
        assertTrue(topic.isSubscribed());
        server.send(json("{\"op\":\"publish\",\"topic\":\"/chatter\",\"msg\":{\"data\":\"hi\"}}"));
        server.send(json("{\"op\":\"publish\",\"topic\":\"/other\",\"msg\":{\"data\":\"not mine\"}}"));
        server.send(json("{\"op\":\"publish\",\"topic\":\"/chatter\",\"msg\":{\"data\":\"again\"}}"));
        assertEquals(new Message("{\"data\":\"hi\"}"), messages.poll(5, TimeUnit.SECONDS));
        assertEquals(new Message("{\"data\":\"again\"}"), messages.poll(5, TimeUnit.SECONDS));
        topic.unsubscribe();
        assertEquals(json("{\"op\":\"unsubscribe\",\"id\":\"subscribe:/chatter:0\",\"topic\":\"/chatter\"}"),
                server.next());
        assertFalse(topic.isSubscribed());
    }

    @Test
    void handlesOfOneTopicShareOneServerSubscriptionAndEachHearsAMessageOnce() throws Exception {
        BlockingQueue<String> heard = new LinkedBlockingQueue<>();
        Topic slow = new Topic(ros, "/status", "pkg/msg/S", 500, 1);
        Topic fast = new Topic(ros, "/status", "pkg/msg/S", 100, 1);
        slow.subscribe(m -> heard.add("slow " + m.toJsonObject().get("n")));
        JsonObject first = server.next();
        assertEquals(500, first.get("throttle_rate").getAsInt());
        fast.subscribe(m -> heard.add("fast " + m.toJsonObject().get("n")));
        JsonObject second = server.next();
        assertEquals(first.get("id"), second.get("id"), "the same subscription, its settings replaced");
        assertEquals(100, second.get("throttle_rate").getAsInt(), "the least throttle asked for");
        server.send(json("{\"op\":\"publish\",\"topic\":\"/status\",\"msg\":{\"n\":1}}"));
        List<String> once = new ArrayList<>(List.of(heard.poll(5, TimeUnit.SECONDS), heard.poll(5, TimeUnit.SECONDS)));
        Collections.sort(once);
        assertEquals(List.of("fast 1", "slow 1"), once);
        fast.unsubscribe();
        assertEquals(500, server.next().get("throttle_rate").getAsInt(), "back to what the remaining handle asks");
        slow.unsubscribe();
        JsonObject unsubscribe = server.next();
        assertEquals("unsubscribe", unsubscribe.get("op").getAsString());
        assertEquals(first.get("id"), unsubscribe.get("id"));
        assertNull(heard.poll(200, TimeUnit.MILLISECONDS));
    }

    @Test
    void trafficCountsWebSocketBytesEachWay() throws Exception {
        Traffic before = ros.traffic();
        Topic topic = new Topic(ros, "/chatter", "std_msgs/msg/String");
        BlockingQueue<Message> messages = new LinkedBlockingQueue<>();
        topic.subscribe(messages::add);
        String sent = server.next().toString();
        String text = "{\"op\":\"publish\",\"topic\":\"/chatter\",\"msg\":{\"data\":\"h\u00e9llo\"}}";
        server.send(text);
        messages.poll(5, TimeUnit.SECONDS);
        Traffic after = ros.traffic();
        assertEquals(server.uri(), after.rosbridge());
        assertTrue(sent.length() >= 126);
        assertEquals(sent.length() + 8, after.bytesUp() - before.bytesUp(), "payload, 4-byte header, 4-byte mask");
        assertEquals(text.getBytes(java.nio.charset.StandardCharsets.UTF_8).length + 2,
                after.bytesDown() - before.bytesDown(), "payload (\u00e9 is 2 bytes) and a 2-byte header");
        assertEquals(1, after.messagesUp() - before.messagesUp());
        assertEquals(1, after.messagesDown() - before.messagesDown());
        assertEquals(200 + 4 + 4, Traffic.frameSize(200, true));
        assertEquals(70000 + 10, Traffic.frameSize(70000, false));
    }

    @Test
    void closeReturnsOnlyAfterARunningCallbackFinished() throws Exception {
        CountDownLatch entered = new CountDownLatch(1);
        CountDownLatch release = new CountDownLatch(1);
        List<String> order = Collections.synchronizedList(new ArrayList<>());
        Topic topic = new Topic(ros, "/chatter", "std_msgs/msg/String");
        topic.subscribe(message -> {
            entered.countDown();
            try {
                release.await();
            } catch (InterruptedException e) {
                Thread.currentThread().interrupt();
            }
            order.add("callback returned");
        });
        server.next("subscribe");
        server.send(json("{\"op\":\"publish\",\"topic\":\"/chatter\",\"msg\":{\"data\":\"hi\"}}"));
        assertTrue(entered.await(5, TimeUnit.SECONDS));
        CompletableFuture<Void> closing = CompletableFuture.runAsync(() -> {
            ros.close();
            order.add("close returned");
        });
        assertThrows(TimeoutException.class, () -> closing.get(200, TimeUnit.MILLISECONDS));
        release.countDown();
        closing.get(5, TimeUnit.SECONDS);
        assertEquals(List.of("callback returned", "close returned"), order);
    }

    @Test
    void closeFromACallbackDoesNotWaitForItself() throws Exception {
        CompletableFuture<Void> closed = new CompletableFuture<>();
        Topic topic = new Topic(ros, "/chatter", "std_msgs/msg/String");
        topic.subscribe(message -> {
            ros.close();
            closed.complete(null);
        });
        server.next("subscribe");
        server.send(json("{\"op\":\"publish\",\"topic\":\"/chatter\",\"msg\":{\"data\":\"hi\"}}"));
        closed.get(2, TimeUnit.SECONDS);
        assertFalse(ros.isConnected());
    }

    @Test
    void publishAdvertisesOnceFirst() throws Exception {
        Topic topic = new Topic(ros, "/cmd", "std_msgs/msg/Bool");
        topic.publish(new Message("{\"data\":true}"));
        topic.publish(new Message("{\"data\":false}"));
        assertEquals(json("{\"op\":\"advertise\",\"id\":\"advertise:/cmd:0\",\"topic\":\"/cmd\","
                + "\"type\":\"std_msgs/msg/Bool\",\"latch\":false,\"queue_size\":100}"), server.next());
        assertEquals(json("{\"op\":\"publish\",\"id\":\"publish:/cmd:1\",\"topic\":\"/cmd\","
                + "\"msg\":{\"data\":true}}"), server.next());
        assertEquals(json("{\"op\":\"publish\",\"id\":\"publish:/cmd:2\",\"topic\":\"/cmd\","
                + "\"msg\":{\"data\":false}}"), server.next());
        topic.unadvertise();
        assertEquals("unadvertise", server.next().get("op").getAsString());
        assertFalse(topic.isAdvertised());
    }

    @Test
    void serviceCallShapeAndReply() throws Exception {
        server.respond(call -> List.of(reply(call, "{\"sum\":5}", true)));
        Service service = new Service(ros, "/add", "example_interfaces/srv/AddTwoInts");
        ServiceResponse response = service.callServiceAndWait(new ServiceRequest("{\"a\":2,\"b\":3}"));
        assertEquals(json("{\"op\":\"call_service\",\"id\":\"call_service:/add:0\",\"service\":\"/add\","
                + "\"type\":\"example_interfaces/srv/AddTwoInts\",\"args\":{\"a\":2,\"b\":3},\"timeout\":5.0}"),
                server.next());
        assertTrue(response.getResult());
        assertEquals(5, response.toJsonObject().get("sum").getAsInt());
        assertEquals(0, ros.pendingCallCount());
    }

    @Test
    void failedServiceCallIsAClearFailureNotAHang() {
        server.respond(call -> List.of(reply(call, "\"Service /nope does not exist\"", false)));
        Service service = new Service(ros, "/nope", "std_srvs/srv/Trigger");
        ServiceFailedException error = assertThrows(ServiceFailedException.class,
                () -> service.callServiceAndWait(new ServiceRequest()));
        assertEquals("Service /nope does not exist", error.getReason());
        assertEquals("/nope", error.getService());
        assertTrue(error.getMessage().contains("/nope"));
        assertEquals(0, ros.pendingCallCount());
    }

    @Test
    void failedCallReachesCallbackAsFailedResponse() throws Exception {
        server.respond(call -> List.of(reply(call, "\"boom\"", false)));
        CompletableFuture<ServiceResponse> got = new CompletableFuture<>();
        new Service(ros, "/x", "std_srvs/srv/Trigger").callService(new ServiceRequest(), got::complete);
        ServiceResponse response = got.get(5, TimeUnit.SECONDS);
        assertFalse(response.getResult());
        assertTrue(response.getError().contains("boom"), response.getError());
    }

    @Test
    void unansweredCallTimesOutAndIsForgotten() throws Exception {
        Service service = new Service(ros, "/slow", "std_srvs/srv/Trigger");
        RosTimeoutException error = assertThrows(RosTimeoutException.class,
                () -> service.callServiceAndWait(new ServiceRequest(), Duration.ofMillis(200)));
        assertTrue(error.getMessage().contains("/slow"), error.getMessage());
        assertEquals(0, ros.pendingCallCount());
        // A reply arriving after the timeout is dropped quietly and leaves the connection usable.
        JsonObject call = server.next("call_service");
        server.send(reply(call, "{\"success\":true}", true));
        server.respond(next -> List.of(reply(next, "{\"success\":true,\"message\":\"\"}", true)));
        assertTrue(service.callServiceAndWait(new ServiceRequest()).toJsonObject().get("success").getAsBoolean());
    }

    @Test
    void concurrentCallsEachGetTheirOwnReply() throws Exception {
        List<JsonObject> calls = new ArrayList<>();
        CountDownLatch all = new CountDownLatch(20);
        server.respond(call -> {
            synchronized (calls) {
                calls.add(call);
                all.countDown();
            }
            return List.of();
        });
        Service service = new Service(ros, "/echo", "x/srv/Echo");
        List<CompletableFuture<ServiceResponse>> futures = new ArrayList<>();
        for (int i = 0; i < 20; i++) {
            int n = i;
            futures.add(CompletableFuture.supplyAsync(() -> service.callServiceAndWait(
                    new ServiceRequest("{\"n\":" + n + "}"))));
        }
        assertTrue(all.await(5, TimeUnit.SECONDS));
        synchronized (calls) {
            for (int i = calls.size() - 1; i >= 0; i--) {
                JsonObject call = calls.get(i);
                server.send(reply(call, "{\"n\":" + call.getAsJsonObject("args").get("n") + "}", true));
            }
        }
        for (int i = 0; i < 20; i++) {
            assertEquals(i, futures.get(i).get(5, TimeUnit.SECONDS).toJsonObject().get("n").getAsInt());
        }
        assertEquals(0, ros.pendingCallCount());
    }

    @Test
    void droppedConnectionFailsPendingCallsAndReconnectsWithRegistrations() throws Exception {
        BlockingQueue<Message> messages = new LinkedBlockingQueue<>();
        new Topic(ros, "/status", "std_msgs/msg/Bool").subscribe(messages::add);
        Topic out = new Topic(ros, "/cmd", "std_msgs/msg/Bool");
        out.advertise();
        JsonObject subscribe = server.next("subscribe");
        JsonObject advertise = server.next("advertise");
        CountDownLatch down = new CountDownLatch(1);
        CountDownLatch up = new CountDownLatch(1);
        ros.addRosHandler(new RosHandler() {
            @Override
            public void handleConnection() {
                up.countDown();
            }

            @Override
            public void handleDisconnection() {
                down.countDown();
            }
        });
        CompletableFuture<ServiceResponse> pending = new Service(ros, "/never", "std_srvs/srv/Trigger")
                .callAsync(new ServiceRequest(), Duration.ofSeconds(30));
        server.next("call_service");
        server.dropClient();
        RosException lost = assertThrows(RosException.class, () -> {
            try {
                pending.get(5, TimeUnit.SECONDS);
            } catch (java.util.concurrent.ExecutionException e) {
                throw e.getCause();
            }
        });
        assertTrue(lost.getMessage().contains("lost"), lost.getMessage());
        assertTrue(down.await(5, TimeUnit.SECONDS));
        server.awaitClient();
        assertTrue(up.await(5, TimeUnit.SECONDS));
        ros.awaitConnected(Duration.ofSeconds(5));
        List<JsonObject> resent = List.of(server.next(), server.next());
        assertTrue(resent.contains(subscribe), resent.toString());
        assertTrue(resent.contains(advertise), resent.toString());
        server.send(json("{\"op\":\"publish\",\"topic\":\"/status\",\"msg\":{\"data\":true}}"));
        assertNotNull(messages.poll(5, TimeUnit.SECONDS));
        assertEquals(0, ros.pendingCallCount());
    }

    @Test
    void disconnectStopsReconnecting() throws Exception {
        ros.disconnect();
        assertNull(server.poll(Duration.ofMillis(300)));
        assertFalse(ros.isConnected());
        assertThrows(RosException.class, () -> ros.send(new JsonObject()));
    }

    @Test
    void fragmentsAreReassembled() throws Exception {
        BlockingQueue<Message> messages = new LinkedBlockingQueue<>();
        new Topic(ros, "/big", "std_msgs/msg/String").subscribe(messages::add);
        String whole = "{\"op\":\"publish\",\"topic\":\"/big\",\"msg\":{\"data\":\"abcdefghij\"}}";
        int third = whole.length() / 3;
        String[] parts = {whole.substring(0, third), whole.substring(third, 2 * third), whole.substring(2 * third)};
        // Out of order, with the float total rosbridge 2.1.0 sends.
        for (int num : new int[] {2, 0, 1}) {
            JsonObject fragment = new JsonObject();
            fragment.addProperty("op", "fragment");
            fragment.addProperty("id", "f1");
            fragment.addProperty("data", parts[num]);
            fragment.addProperty("num", num);
            fragment.addProperty("total", 3.0);
            server.send(fragment);
        }
        assertEquals(new Message("{\"data\":\"abcdefghij\"}"), messages.poll(5, TimeUnit.SECONDS));
    }

    @Test
    void malformedInputReachesHandlersAndConnectionSurvives() throws Exception {
        BlockingQueue<Throwable> errors = new LinkedBlockingQueue<>();
        ros.addRosHandler(new RosHandler() {
            @Override
            public void handleError(Throwable error) {
                errors.add(error);
            }
        });
        server.send("not json");
        server.send("{\"op\":\"mystery\"}");
        assertTrue(errors.poll(5, TimeUnit.SECONDS).getMessage().contains("malformed"));
        assertTrue(errors.poll(5, TimeUnit.SECONDS).getMessage().contains("mystery"));
        assertTrue(ros.isConnected());
    }

    @Test
    void callbackExceptionsAreReportedNotLost() throws Exception {
        BlockingQueue<Throwable> errors = new LinkedBlockingQueue<>();
        ros.addRosHandler(new RosHandler() {
            @Override
            public void handleError(Throwable error) {
                errors.add(error);
            }
        });
        new Topic(ros, "/t", "std_msgs/msg/Bool").subscribe(m -> {
            throw new IllegalStateException("callback broke");
        });
        server.send(json("{\"op\":\"publish\",\"topic\":\"/t\",\"msg\":{\"data\":true}}"));
        assertTrue(errors.poll(5, TimeUnit.SECONDS).getMessage().contains("callback broke"));
    }

    @Test
    void messagesAreImmutable() {
        JsonObject fields = json("{\"data\":1}");
        Message message = new Message(fields);
        fields.addProperty("data", 2);
        message.toJsonObject().addProperty("data", 3);
        assertEquals(1, message.toJsonObject().get("data").getAsInt());
    }

    @Test
    void ros2TimeAndHeader() {
        Header header = new Header(new Time(12, 345), "world");
        assertEquals(json("{\"stamp\":{\"sec\":12,\"nanosec\":345},\"frame_id\":\"world\"}"), header.toJson());
        assertFalse(header.toJson().has("seq"));
        assertEquals(new Time(3, 4), Time.fromJson(json("{\"secs\":3,\"nsecs\":4}")));
        assertThrows(IllegalArgumentException.class, () -> new Time(1, 1_000_000_000L));
    }

    @Test
    void poseFromRollPitchYawAboutFixedAxes() {
        Pose yaw = Pose.fromRpy(1, 2, 3, 0, 0, Math.PI / 2);
        assertEquals(Math.sqrt(0.5), yaw.qz(), 1e-12);
        assertEquals(Math.sqrt(0.5), yaw.qw(), 1e-12);
        // roll 90 then yaw 90 about fixed axes: q = qz * qx
        Pose both = Pose.fromRpy(0, 0, 0, Math.PI / 2, 0, Math.PI / 2);
        assertEquals(0.5, both.qx(), 1e-12);
        assertEquals(0.5, both.qy(), 1e-12);
        assertEquals(0.5, both.qz(), 1e-12);
        assertEquals(0.5, both.qw(), 1e-12);
    }
}
