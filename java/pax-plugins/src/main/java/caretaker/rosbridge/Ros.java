package caretaker.rosbridge;

import com.google.gson.JsonElement;
import com.google.gson.JsonObject;
import com.google.gson.JsonParser;
import java.net.URI;
import java.time.Duration;
import java.time.Instant;
import java.util.List;
import java.util.Map;
import java.util.concurrent.CompletableFuture;
import java.util.concurrent.ConcurrentHashMap;
import java.util.concurrent.CopyOnWriteArrayList;
import java.util.concurrent.ExecutorService;
import java.util.concurrent.Executors;
import java.util.concurrent.ScheduledExecutorService;
import java.util.concurrent.ScheduledFuture;
import java.util.concurrent.ScheduledThreadPoolExecutor;
import java.util.concurrent.ThreadFactory;
import java.util.concurrent.TimeUnit;
import java.util.concurrent.atomic.AtomicLong;
import java.util.concurrent.atomic.AtomicReference;

/**
 * A connection to a rosbridge v2 server. Create it, {@link #connect()}, then make
 * {@link Topic}s and {@link Service}s on it; {@link #close()} when done.
 *
 * <p>After a successful {@link #connect()} the connection is kept up: when it drops, every pending
 * service call fails at once with a {@link RosException} (the server will never answer it), and
 * reconnect attempts follow with exponential back-off; once reconnected, every subscription and
 * advertisement is sent again, so {@link Topic} users see a gap, not a dead topic. Keepalive
 * pings ({@link RosOptions#pingInterval()}) take a server silent for longer than
 * {@link RosOptions#pingTimeout()} for gone.
 *
 * <p>With {@link RosOptions#auth()} set, the {@code auth} message is the first message of every
 * (re)connect (a fresh {@code rand} each time). A bridge that refuses it closes with 1008: the
 * connection then stops reconnecting, and every call and {@link #awaitConnected} fails with a
 * {@link RosAuthException} until {@link #connect()} is called again. A {@code wss://} URI is
 * verified against {@link RosOptions#tls()} (host name included).
 *
 * <p>Thread-safe. Construction does not connect.
 */
public final class Ros implements AutoCloseable {
    private static final System.Logger LOG = System.getLogger(Ros.class.getName());

    /** rosbridge's default port. */
    public static final int DEFAULT_PORT = 9090;

    private final URI uri;
    private final RosOptions options;
    private final Connection connection;
    private final AtomicLong idCounter = new AtomicLong();
    private final Map<String, PendingCall> pendingCalls = new ConcurrentHashMap<>();
    /** Subscription handle id → subscription; several may share a topic. */
    private final Map<String, Subscription> subscriptions = new ConcurrentHashMap<>();
    /** Topic → the one subscribe request the server has for it (shared by every handle). */
    private final Map<String, JsonObject> feeds = new ConcurrentHashMap<>();
    /** Guards changes of {@link #subscriptions} and {@link #feeds} together. */
    private final Object feedLock = new Object();
    private final Map<String, JsonObject> advertisements = new ConcurrentHashMap<>();
    private final Map<String, FragmentBuffer> fragments = new ConcurrentHashMap<>();
    private final List<RosHandler> handlers = new CopyOnWriteArrayList<>();
    private final ExecutorService callbackThread;
    /** The thread callbackThread runs user code on, once started. */
    private final AtomicReference<Thread> callbackWorker = new AtomicReference<>();
    private final ScheduledExecutorService timerThread;

    /** A connection to {@code ws://localhost:9090}. */
    public Ros() {
        this("localhost");
    }

    /** @param host the server's host name; port 9090 */
    public Ros(String host) {
        this(host, DEFAULT_PORT);
    }

    /**
     * @param host the server's host name
     * @param port the server's port
     */
    public Ros(String host, int port) {
        this(URI.create("ws://" + host + ":" + port), RosOptions.defaults());
    }

    /**
     * @param uri the server's WebSocket URI, e.g. {@code ws://127.0.0.1:9090}
     * @param options timeouts and reconnect back-off
     */
    public Ros(URI uri, RosOptions options) {
        if (!"ws".equals(uri.getScheme()) && !"wss".equals(uri.getScheme())) {
            throw new IllegalArgumentException("rosbridge URI must start with ws:// or wss://, got " + uri);
        }
        this.uri = uri;
        this.options = options;
        ThreadFactory callbacks = daemon("rosbridge-callbacks " + uri);
        this.callbackThread = Executors.newSingleThreadExecutor(runnable -> {
            Thread thread = callbacks.newThread(runnable);
            callbackWorker.set(thread);
            return thread;
        });
        ScheduledThreadPoolExecutor timer = new ScheduledThreadPoolExecutor(1, daemon("rosbridge-timer " + uri));
        timer.setRemoveOnCancelPolicy(true); // answered calls leave the queue at once
        this.timerThread = timer;
        this.connection = new Connection(uri, options, new Connection.Events() {
            @Override
            public void opened() {
                connected();
            }

            @Override
            public void lost(RosException failure) {
                Ros.this.lost(failure);
            }

            @Override
            public void error(RosException failure) {
                Ros.this.error(failure);
            }

            @Override
            public void quiet(Instant since) {
                for (RosHandler handler : handlers) {
                    dispatch(() -> handler.handleQuiet(since));
                }
            }

            @Override
            public void received(String text) {
                receive(text);
            }
        }, timerThread);
    }

    private static ThreadFactory daemon(String name) {
        return runnable -> {
            Thread thread = new Thread(runnable, name);
            thread.setDaemon(true);
            return thread;
        };
    }

    /** @return the server's URI */
    public URI getUri() {
        return uri;
    }

    /** @return the options this connection was made with */
    public RosOptions getOptions() {
        return options;
    }

    /** @return the host of the server */
    public String getHostname() {
        return uri.getHost();
    }

    /** @return the port of the server */
    public int getPort() {
        return uri.getPort();
    }

    /**
     * Connects and waits for the connection, at most {@link RosOptions#timeout()}. Does nothing if
     * already connected. From now on the connection is kept up until {@link #disconnect()}.
     *
     * <p>With authentication configured, it also waits for one answer from the server after the
     * {@code auth} message (to {@code /rosapi/get_ros_version}; a failed answer counts too), so a
     * refusal is reported here rather than by the first call.
     *
     * @throws RosAuthException the server refused the authentication
     * @throws RosException the server refused or is not there
     * @throws RosTimeoutException no connection within the timeout
     */
    public void connect() {
        connection.connect();
        if (options.auth() != null) {
            confirmAuthentication();
        }
    }

    /**
     * Connects as {@link #connect()} does, and tries again while the server does not answer in time,
     * until {@code patience} has run out: a starved or far server is slow, not gone. A refused
     * connection or authentication fails at once.
     *
     * @param patience how long to keep trying after timeouts (a link's outage budget)
     * @throws RosTimeoutException no connection within the timeout, on the last try
     */
    public void connect(Duration patience) {
        long deadline = System.nanoTime() + patience.toNanos();
        while (true) {
            try {
                connect();
                return;
            } catch (RosTimeoutException e) {
                if (System.nanoTime() - deadline >= 0) {
                    throw e;
                }
                LOG.log(System.Logger.Level.WARNING, e.getMessage() + "; trying again (slow, perhaps not gone)");
            }
        }
    }

    private void confirmAuthentication() {
        try {
            new Service(this, "/rosapi/get_ros_version", null).callServiceAndWait(new ServiceRequest(),
                    options.timeout());
        } catch (ServiceFailedException e) {
            LOG.log(System.Logger.Level.DEBUG, "authenticated; the check's answer was a failure: " + e.getMessage());
        } catch (RosException e) {
            connection.disconnect();
            String refusal = connection.refusal();
            if (refusal != null) {
                throw new RosAuthException(refusal);
            }
            throw new RosException("no answer from rosbridge at " + uri + " after authenticating: " + e.getMessage(), e);
        }
    }

    /** Sends every registration again and tells the handlers; runs after each (re)connect. */
    private void connected() {
        for (JsonObject advertise : advertisements.values()) {
            trySend(advertise);
        }
        for (JsonObject feed : feeds.values()) {
            trySend(feed);
        }
        for (RosHandler handler : handlers) {
            callbackThread.execute(() -> runHandler(handler::handleConnection));
        }
    }

    private void trySend(JsonObject message) {
        try {
            send(message);
        } catch (RosException e) {
            LOG.log(System.Logger.Level.WARNING, "re-sending after reconnect failed: " + e.getMessage());
        }
    }

    /**
     * Closes the connection and stops reconnecting. Pending calls fail. Subscriptions and
     * advertisements are kept and re-sent by the next {@link #connect()}.
     */
    public void disconnect() {
        connection.disconnect();
    }

    /**
     * Disconnects and releases this connection's threads; it cannot be connected again.
     *
     * <p>Returns once callbacks already delivered have run (at most the options' timeout): the
     * caller may tear down what they call next, e.g. a Python listener reached through JPype at
     * interpreter exit. Called from a callback, it does not wait for itself.
     */
    @Override
    public void close() {
        connection.close();
        callbackThread.shutdown();
        timerThread.shutdownNow();
        if (Thread.currentThread() == callbackWorker.get()) {
            return;
        }
        try {
            if (!callbackThread.awaitTermination(options.timeout().toMillis(), TimeUnit.MILLISECONDS)) {
                LOG.log(System.Logger.Level.WARNING, "a callback of " + uri + " still runs " + options.timeout()
                        + " after close()");
            }
        } catch (InterruptedException e) {
            Thread.currentThread().interrupt();
        }
    }

    /**
     * @return what this connection carried so far, across reconnects: WebSocket frames each way
     *     (payload and frame headers; TLS and TCP/IP overhead not included)
     */
    public Traffic traffic() {
        return connection.traffic();
    }

    /**
     * @return {@link System#nanoTime()} when anything (a message, a pong) last came from the
     *     server, or when the connection last opened
     */
    public long lastHeardNanos() {
        return connection.lastHeardNanos();
    }

    /** @return whether the connection is currently up */
    public boolean isConnected() {
        return connection.isConnected();
    }

    /**
     * @return when the connection was lost (for a silent server: when it was last heard); null
     *     while connected or before the first connect
     */
    public Instant lostSince() {
        return connection.lostSince();
    }

    /**
     * @return when the server was last heard, while nothing has come from it for a few keepalive
     *         intervals (the connection still up); null while it is heard
     */
    public Instant quietSince() {
        return connection.isConnected() ? connection.quietSince() : null;
    }

    /**
     * Blocks until the connection is up, e.g. after a drop.
     *
     * @param timeout how long to wait
     * @throws RosTimeoutException still not connected after {@code timeout}
     * @throws RosAuthException the server refused this client's authentication
     */
    public void awaitConnected(Duration timeout) {
        connection.awaitConnected(timeout);
    }

    /** @param handler told about connects, disconnects and errors */
    public void addRosHandler(RosHandler handler) {
        handlers.add(handler);
    }

    /** @param handler a handler added before; no effect otherwise */
    public void removeRosHandler(RosHandler handler) {
        handlers.remove(handler);
    }

    /** @return a number unique on this connection, for message ids (starts at 0 like jrosbridge) */
    public long nextId() {
        return idCounter.getAndIncrement();
    }

    /**
     * Sends one message, waiting at most {@link RosOptions#timeout()} for the socket to take it.
     *
     * @param message a complete rosbridge message with an {@code op}
     * @throws NotConnectedException not connected: the server cannot have received it
     * @throws RosException the send failed
     */
    public void send(JsonObject message) {
        connection.send(message);
    }

    // ---- registrations used by Topic and Service --------------------------------------------

    /**
     * Adds a subscription. The server gets one subscription per topic whatever the number of
     * handles (rosbridge sends every message once per subscription id, and publish messages do not
     * say which id they are for): its throttle is the smallest asked for, its queue the longest
     * (0 = the server's default), and it is sent again whenever those change.
     */
    void subscribe(String id, String topic, String type, int throttleRate, int queueLength, TopicCallback callback) {
        synchronized (feedLock) {
            subscriptions.put(id, new Subscription(id, topic, type, throttleRate, queueLength, callback));
            updateFeed(topic);
        }
    }

    void unsubscribe(String id) {
        synchronized (feedLock) {
            Subscription gone = subscriptions.remove(id);
            if (gone != null) {
                updateFeed(gone.topic());
            }
        }
    }

    /** Makes the server's subscription to {@code topic} match the handles; caller holds feedLock. */
    private void updateFeed(String topic) {
        List<Subscription> handles = subscriptions.values().stream().filter(s -> s.topic().equals(topic)).toList();
        JsonObject current = feeds.get(topic);
        if (handles.isEmpty()) {
            if (current != null) {
                feeds.remove(topic);
                JsonObject request = new JsonObject();
                request.addProperty(Protocol.FIELD_OP, Protocol.OP_UNSUBSCRIBE);
                request.add(Protocol.FIELD_ID, current.get(Protocol.FIELD_ID));
                request.addProperty(Protocol.FIELD_TOPIC, topic);
                sendIfConnected(request);
            }
            return;
        }
        String type = handles.stream().map(Subscription::type).filter(t -> t != null).findFirst().orElse(null);
        int throttle = handles.stream().mapToInt(Subscription::throttleRate).min().orElse(0);
        int queue = handles.stream().anyMatch(s -> s.queueLength() == 0) ? 0
                : handles.stream().mapToInt(Subscription::queueLength).max().orElse(0);
        JsonObject request = new JsonObject();
        request.addProperty(Protocol.FIELD_OP, Protocol.OP_SUBSCRIBE);
        request.addProperty(Protocol.FIELD_ID, current != null ? current.get(Protocol.FIELD_ID).getAsString()
                : handles.get(0).id());
        request.addProperty(Protocol.FIELD_TOPIC, topic);
        if (type != null) {
            request.addProperty(Protocol.FIELD_TYPE, type);
        }
        request.addProperty(Protocol.FIELD_COMPRESSION, "none");
        request.addProperty(Protocol.FIELD_THROTTLE_RATE, throttle);
        request.addProperty(Protocol.FIELD_QUEUE_LENGTH, queue);
        if (!request.equals(current)) {
            feeds.put(topic, request);
            sendIfConnected(request); // the same id again: the server replaces its settings
        }
    }

    void advertise(String id, JsonObject request) {
        advertisements.put(id, request);
        sendIfConnected(request);
    }

    void unadvertise(String id, JsonObject request) {
        if (advertisements.remove(id) != null) {
            sendIfConnected(request);
        }
    }

    /** Registrations survive a dropped connection: they are re-sent on reconnect. */
    private void sendIfConnected(JsonObject request) {
        if (isConnected()) {
            trySend(request);
        }
    }

    /**
     * Sends a call and registers it until its reply. With a timeout, the timer thread fails it
     * then; without (null), the caller must wait with its own timeout and {@link #forgetCall}
     * on expiry — the blocking path does that, so it costs no timer task per call.
     */
    CompletableFuture<ServiceResponse> callService(String id, String service, JsonObject request, Duration timeout) {
        CompletableFuture<ServiceResponse> future = new CompletableFuture<>();
        pendingCalls.put(id, new PendingCall(service, future));
        try {
            if (timeout != null) {
                ScheduledFuture<?> timer = timerThread.schedule(() -> forgetCall(id, timeout), timeout.toNanos(),
                        TimeUnit.NANOSECONDS);
                future.whenComplete((response, failure) -> timer.cancel(false));
            }
            send(request);
        } catch (RuntimeException e) {
            pendingCalls.remove(id);
            future.completeExceptionally(e instanceof RosException ? e : new RosException(e.getMessage(), e));
        }
        return future;
    }

    /** Drops a call that got no reply within {@code timeout}; a late reply is then ignored. */
    void forgetCall(String id, Duration timeout) {
        PendingCall call = pendingCalls.remove(id);
        if (call != null) {
            call.future().completeExceptionally(new RosTimeoutException("call_service " + call.service(), timeout));
        }
    }

    /** Number of service calls awaiting a reply, so tests can check nothing leaks. */
    int pendingCallCount() {
        return pendingCalls.size();
    }

    /** Runs user code on the callback thread; an exception is reported, never lost. */
    void dispatch(Runnable callback) {
        try {
            callbackThread.execute(() -> runHandler(callback));
        } catch (java.util.concurrent.RejectedExecutionException e) {
            LOG.log(System.Logger.Level.DEBUG, "callback after close dropped");
        }
    }

    private void runHandler(Runnable callback) {
        try {
            callback.run();
        } catch (RuntimeException e) {
            error(new RosException("a callback failed: " + e, e));
        }
    }

    private void error(Throwable error) {
        LOG.log(System.Logger.Level.WARNING, error.getMessage());
        for (RosHandler handler : handlers) {
            dispatch(() -> {
                try {
                    handler.handleError(error);
                } catch (RuntimeException e) {
                    LOG.log(System.Logger.Level.WARNING, "RosHandler.handleError threw", e);
                }
            });
        }
    }

    // ---- receiving ---------------------------------------------------------------------------

    private void receive(String text) {
        try {
            receiveMessage(text);
        } catch (RuntimeException e) {
            error(new RosException("cannot handle message from " + uri + ": " + e.getMessage(), e));
        }
    }

    private void receiveMessage(String text) {
        JsonObject message;
        try {
            message = JsonParser.parseString(text).getAsJsonObject();
        } catch (RuntimeException e) {
            error(new RosException("malformed message from " + uri + ": " + abbreviate(text)));
            return;
        }
        String op = stringField(message, Protocol.FIELD_OP);
        if (op == null) {
            error(new RosException("message without op from " + uri + ": " + abbreviate(text)));
            return;
        }
        switch (op) {
            case Protocol.OP_PUBLISH -> receivePublish(message);
            case Protocol.OP_SERVICE_RESPONSE -> receiveServiceResponse(message);
            case Protocol.OP_FRAGMENT -> receiveFragment(message);
            case Protocol.OP_STATUS -> LOG.log(System.Logger.Level.INFO, "rosbridge status: " + message);
            default -> error(new RosException("unsupported op '" + op + "' from " + uri));
        }
    }

    private void receivePublish(JsonObject message) {
        String topic = stringField(message, Protocol.FIELD_TOPIC);
        JsonElement body = message.get(Protocol.FIELD_MSG);
        if (topic == null || body == null || !body.isJsonObject()) {
            error(new RosException("publish without topic or msg object from " + uri));
            return;
        }
        Message received = new Message(body.getAsJsonObject());
        for (Subscription subscription : subscriptions.values()) {
            if (subscription.topic().equals(topic)) {
                dispatch(() -> subscription.callback().handleMessage(received));
            }
        }
    }

    private void receiveServiceResponse(JsonObject message) {
        String id = stringField(message, Protocol.FIELD_ID);
        PendingCall call = id == null ? null : pendingCalls.remove(id);
        if (call == null) {
            // Late replies to calls that already timed out land here; they are not errors.
            LOG.log(System.Logger.Level.DEBUG, "service_response for no pending call: " + id);
            return;
        }
        JsonElement values = message.get(Protocol.FIELD_VALUES);
        JsonElement result = message.get(Protocol.FIELD_RESULT);
        boolean ok = result == null || (result.isJsonPrimitive() && result.getAsJsonPrimitive().isBoolean()
                && result.getAsBoolean());
        if (ok && values != null && values.isJsonObject()) {
            call.future().complete(new ServiceResponse(values.getAsJsonObject()));
        } else if (ok && (values == null || values.isJsonNull())) {
            call.future().complete(new ServiceResponse(new JsonObject()));
        } else {
            String reason = values == null || values.isJsonNull() ? "no reason given"
                    : values.isJsonPrimitive() ? values.getAsString() : values.toString();
            call.future().completeExceptionally(new ServiceFailedException(call.service(), reason));
        }
    }

    private void receiveFragment(JsonObject message) {
        String id = stringField(message, Protocol.FIELD_ID);
        JsonElement data = message.get(Protocol.FIELD_DATA);
        JsonElement num = message.get(Protocol.FIELD_NUM);
        JsonElement total = message.get(Protocol.FIELD_TOTAL);
        if (id == null || data == null || num == null || total == null) {
            error(new RosException("fragment without id, data, num or total from " + uri));
            return;
        }
        // rosbridge 2.1.0 computes total with '/', so it may arrive as a float like 3.0
        int count = (int) Math.ceil(total.getAsDouble());
        FragmentBuffer buffer = fragments.computeIfAbsent(id, key -> new FragmentBuffer(count));
        String whole = buffer.add((int) num.getAsDouble(), data.getAsString());
        if (whole != null) {
            fragments.remove(id);
            receive(whole);
        }
    }

    private static String stringField(JsonObject message, String field) {
        JsonElement element = message.get(field);
        return element != null && element.isJsonPrimitive() ? element.getAsString() : null;
    }

    private static String abbreviate(String text) {
        return text.length() <= 200 ? text : text.substring(0, 200) + "...";
    }

    /** The connection went down: pending calls fail with {@code failure}; handlers hear of it. */
    private void lost(RosException failure) {
        for (String id : List.copyOf(pendingCalls.keySet())) {
            PendingCall call = pendingCalls.remove(id);
            if (call != null) {
                call.future().completeExceptionally(failure);
            }
        }
        fragments.clear();
        for (RosHandler handler : handlers) {
            dispatch(handler::handleDisconnection);
        }
    }

    private record PendingCall(String service, CompletableFuture<ServiceResponse> future) {
    }

    private record Subscription(String id, String topic, String type, int throttleRate, int queueLength,
            TopicCallback callback) {
    }
}
