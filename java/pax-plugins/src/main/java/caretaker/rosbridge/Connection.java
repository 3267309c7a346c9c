package caretaker.rosbridge;

import com.google.gson.JsonObject;
import java.net.URI;
import java.net.http.HttpClient;
import java.net.http.WebSocket;
import java.nio.ByteBuffer;
import java.security.SecureRandom;
import java.time.Duration;
import java.time.Instant;
import java.util.Locale;
import java.util.concurrent.CompletableFuture;
import java.util.concurrent.CompletionStage;
import java.util.concurrent.ExecutionException;
import java.util.concurrent.RejectedExecutionException;
import java.util.concurrent.ScheduledExecutorService;
import java.util.concurrent.TimeUnit;
import java.util.concurrent.TimeoutException;
import java.util.concurrent.atomic.AtomicLong;

/**
 * The WebSocket under a {@link Ros}: opening it (with the {@code auth} message first), sending on
 * it, keeping it alive with pings, noticing its loss, and reconnecting with back-off until
 * {@link #disconnect()}. What the frames mean is {@link Ros}'s business, told through
 * {@link Events}.
 */
final class Connection implements AutoCloseable {
    private static final System.Logger LOG = System.getLogger(Connection.class.getName());

    /** What the connection tells its {@link Ros}; called without any lock held. */
    interface Events {
        /** The connection is up (again): re-send registrations, tell handlers. */
        void opened();

        /**
         * The connection is down: fail what waits for an answer.
         *
         * @param failure what pending calls fail with
         */
        void lost(RosException failure);

        /**
         * Nothing came from the server for a few keepalive intervals: it may be gone, long before
         * the connection is given up; or it came again ({@code since} null).
         *
         * @param since when the server was last heard, or null when it is heard again
         */
        void quiet(Instant since);

        /**
         * Something failed that no caller waits for.
         *
         * @param error what failed
         */
        void error(RosException error);

        /**
         * A complete text message arrived.
         *
         * @param text the message
         */
        void received(String text);
    }

    private final URI uri;
    private final RosOptions options;
    private final HttpClient http;
    private final Events events;
    private final ScheduledExecutorService timerThread;
    private final SecureRandom random = new SecureRandom();
    private final Keepalive keepalive;
    /** Guards {@link #socket}, {@link #wanted}, {@link #closed} and {@link #refusal}. */
    private final Object connectionLock = new Object();
    /** Serialises sends: java.net.http allows one outstanding send per WebSocket. */
    private final Object sendLock = new Object();
    private WebSocket socket;
    private boolean wanted;
    private boolean closed;
    /** Why the server refused authentication, or null. */
    private String refusal;
    /** When the connection was lost; null while connected and before the first connect. */
    private volatile Instant lostSince;
    private final AtomicLong bytesUp = new AtomicLong();
    private final AtomicLong bytesDown = new AtomicLong();
    private final AtomicLong messagesUp = new AtomicLong();
    private final AtomicLong messagesDown = new AtomicLong();

    Connection(URI uri, RosOptions options, Events events, ScheduledExecutorService timerThread) {
        this.uri = uri;
        this.options = options;
        this.events = events;
        this.timerThread = timerThread;
        // Frames are handled on the client's own selector thread instead of being handed to a
        // pool thread first: one thread switch less per reply. Safe because the listener never
        // blocks and never sends; user code runs on Ros's callback thread.
        HttpClient.Builder builder = HttpClient.newBuilder().connectTimeout(options.timeout()).executor(Runnable::run);
        if (options.tls() != null) {
            builder.sslContext(options.tls());
        }
        this.http = builder.build();
        this.keepalive = new Keepalive("rosbridge-keepalive " + uri, options.pingInterval(), options.pingTimeout(),
                this::ping, this::silent, events::quiet, () -> events.quiet(null));
    }

    /** @see Ros#connect() */
    void connect() {
        synchronized (connectionLock) {
            if (closed) {
                throw new RosException("connection to " + uri + " is closed; make a new Ros");
            }
            if (socket != null) {
                return;
            }
            refusal = null;
        }
        Opened opened = open();
        String endedAtOnce;
        synchronized (connectionLock) {
            endedAtOnce = publish(opened);
            wanted = endedAtOnce == null;
            if (refusal != null) {
                throw new RosAuthException(refusal);
            }
        }
        if (endedAtOnce != null) {
            throw new RosException("connection to rosbridge at " + uri + " closed at once: " + endedAtOnce);
        }
        events.opened();
    }

    /** @return why the server refused this client's authentication, or null */
    String refusal() {
        synchronized (connectionLock) {
            return refusal;
        }
    }

    /**
     * Makes {@code opened} the connection unless it already ended; caller holds connectionLock.
     *
     * @return null when published, else why the connection already ended
     */
    private String publish(Opened opened) {
        if (opened.listener().endedBecause != null) {
            return opened.listener().endedBecause;
        }
        socket = opened.socket();
        lostSince = null;
        keepalive.heard();
        connectionLock.notifyAll();
        return null;
    }

    /** Opens a WebSocket and sends the {@code auth} message first, if configured. */
    private Opened open() {
        Listener listener = new Listener();
        CompletableFuture<WebSocket> future = http.newWebSocketBuilder()
                .connectTimeout(options.timeout())
                .buildAsync(uri, listener);
        WebSocket opened;
        try {
            opened = future.get(options.timeout().toMillis(), TimeUnit.MILLISECONDS);
            if (options.auth() != null) {
                String auth = options.auth().message(uri.getHost(), Instant.now(), random).toString();
                try {
                    opened.sendText(auth, true).get(options.timeout().toMillis(), TimeUnit.MILLISECONDS);
                    sent(Traffic.utf8Length(auth));
                } catch (ExecutionException | TimeoutException | InterruptedException e) {
                    opened.abort();
                    throw e;
                }
            }
        } catch (TimeoutException e) {
            future.cancel(true);
            throw new RosTimeoutException("connect to " + uri, options.timeout());
        } catch (InterruptedException e) {
            Thread.currentThread().interrupt();
            throw new RosException("interrupted while connecting to " + uri, e);
        } catch (ExecutionException e) {
            Throwable cause = e.getCause() == null ? e : e.getCause();
            if (cause instanceof java.net.http.HttpTimeoutException) { // the HTTP client's own clock ran out first
                throw new RosTimeoutException("connect to " + uri, options.timeout());
            }
            throw new RosException("cannot connect to rosbridge at " + uri + ": " + describe(cause), cause);
        }
        return new Opened(opened, listener);
    }

    static String describe(Throwable error) {
        Throwable root = error;
        while (root.getCause() != null && root.getCause() != root) {
            if (root instanceof java.net.ConnectException) {
                return "connection refused";
            }
            root = root.getCause();
        }
        String text = root.getMessage();
        return text == null || text.isEmpty() ? root.getClass().getSimpleName() : text;
    }

    /** @see Ros#disconnect() */
    void disconnect() {
        WebSocket old;
        synchronized (connectionLock) {
            wanted = false;
            old = socket;
            socket = null;
        }
        if (old != null) {
            try {
                old.sendClose(WebSocket.NORMAL_CLOSURE, "").get(options.timeout().toMillis(), TimeUnit.MILLISECONDS);
                sent(2);
            } catch (InterruptedException e) {
                Thread.currentThread().interrupt();
            } catch (ExecutionException | TimeoutException e) {
                LOG.log(System.Logger.Level.DEBUG, "close handshake with " + uri + " failed: " + e);
            }
            old.abort();
            lostSince = Instant.now();
            events.lost(new RosException("connection to rosbridge at " + uri
                    + " lost (disconnected by this client) before the reply came"));
        }
    }

    /** Disconnects for good and stops the keepalive. */
    @Override
    public void close() {
        disconnect();
        synchronized (connectionLock) {
            closed = true;
        }
        keepalive.close();
    }

    /** @see Ros#lastHeardNanos() */
    long lastHeardNanos() {
        return keepalive.lastHeardNanos();
    }

    /** @see Ros#traffic() */
    Traffic traffic() {
        return new Traffic(uri, bytesUp.get(), bytesDown.get(), messagesUp.get(), messagesDown.get());
    }

    /** Counts one message sent with {@code payload} bytes. */
    private void sent(long payload) {
        bytesUp.addAndGet(Traffic.frameSize(payload, true));
        messagesUp.incrementAndGet();
    }

    /** Counts one message received with {@code payload} bytes. */
    private void received(long payload) {
        bytesDown.addAndGet(Traffic.frameSize(payload, false));
        messagesDown.incrementAndGet();
    }

    /** @see Ros#isConnected() */
    boolean isConnected() {
        synchronized (connectionLock) {
            return socket != null;
        }
    }

    /** @see Ros#quietSince() */
    Instant quietSince() {
        return keepalive.quietSince();
    }

    /** @see Ros#lostSince() */
    Instant lostSince() {
        return lostSince;
    }

    /** @see Ros#awaitConnected(Duration) */
    void awaitConnected(Duration timeout) {
        long deadline = System.nanoTime() + timeout.toNanos();
        synchronized (connectionLock) {
            while (socket == null) {
                if (refusal != null) {
                    throw new RosAuthException(refusal);
                }
                long left = deadline - System.nanoTime();
                if (left <= 0) {
                    throw new RosTimeoutException("reconnect to " + uri, timeout);
                }
                try {
                    TimeUnit.NANOSECONDS.timedWait(connectionLock, left);
                } catch (InterruptedException e) {
                    Thread.currentThread().interrupt();
                    throw new RosException("interrupted while waiting for " + uri, e);
                }
            }
        }
    }

    /** @see Ros#send(JsonObject) */
    void send(JsonObject message) {
        WebSocket current;
        synchronized (connectionLock) {
            current = socket;
        }
        if (current == null) {
            throw new NotConnectedException("not connected to rosbridge at " + uri);
        }
        String text = message.toString();
        synchronized (sendLock) {
            try {
                current.sendText(text, true).get(options.timeout().toMillis(), TimeUnit.MILLISECONDS);
                sent(Traffic.utf8Length(text));
            } catch (InterruptedException e) {
                Thread.currentThread().interrupt();
                throw new RosException("interrupted while sending to " + uri, e);
            } catch (ExecutionException e) {
                throw new RosException("sending to " + uri + " failed: " + describe(e), e.getCause());
            } catch (TimeoutException e) {
                throw new RosTimeoutException("send to " + uri, options.timeout());
            }
        }
    }

    // ---- losing and regaining the connection -------------------------------------------------

    /**
     * {@code which} ended (if it is the connection): fail pending calls, tell handlers, reconnect.
     *
     * @param since when it was lost (for a silent server, when it was last heard)
     */
    private void lost(WebSocket which, String reason, Instant since) {
        boolean reconnect;
        synchronized (connectionLock) {
            if (which != socket) {
                return;
            }
            socket = null;
            lostSince = since;
            reconnect = wanted && !closed;
        }
        events.lost(new RosException("connection to rosbridge at " + uri + " lost (" + reason
                + ") before the reply came"));
        if (reconnect) {
            scheduleReconnect(options.reconnectMin());
        }
    }

    /** The server refused this client's authentication on {@code which}: no reconnecting. */
    private void refused(WebSocket which, String reason) {
        RosAuthException failure;
        synchronized (connectionLock) {
            refusal = "rosbridge at " + uri + " refused authentication (close 1008: " + reason
                    + "); check the binding's secret or token";
            failure = new RosAuthException(refusal);
            if (which != socket) {
                return; // a connection not yet published: connect() or reconnect() reports it
            }
            socket = null;
            wanted = false;
            lostSince = Instant.now();
        }
        events.lost(failure);
        events.error(failure);
    }

    /** Sends a WebSocket ping on the connection (keepalive thread). */
    private void ping() {
        WebSocket current;
        synchronized (connectionLock) {
            current = socket;
        }
        if (current == null) {
            return;
        }
        synchronized (sendLock) {
            try {
                current.sendPing(ByteBuffer.allocate(0)).get(options.timeout().toMillis(), TimeUnit.MILLISECONDS);
                sent(0);
            } catch (InterruptedException e) {
                Thread.currentThread().interrupt();
            } catch (ExecutionException | TimeoutException e) {
                LOG.log(System.Logger.Level.DEBUG, "ping to " + uri + " not sent: " + e);
            }
        }
    }

    /** The server stayed silent past the ping timeout: drop the connection and reconnect. */
    private void silent(Instant lastHeard) {
        WebSocket current;
        synchronized (connectionLock) {
            current = socket;
        }
        if (current == null) {
            return;
        }
        LOG.log(System.Logger.Level.WARNING, "rosbridge at " + uri + " silent since " + lastHeard + ": reconnecting");
        current.abort();
        lost(current, "nothing heard for " + Durations.seconds(options.pingTimeout()) + " s, keepalive", lastHeard);
    }

    private void scheduleReconnect(Duration delay) {
        try {
            timerThread.schedule(() -> reconnect(delay), delay.toNanos(), TimeUnit.NANOSECONDS);
        } catch (RejectedExecutionException e) {
            LOG.log(System.Logger.Level.DEBUG, "no reconnect: connection closed");
        }
    }

    private void reconnect(Duration lastDelay) {
        synchronized (connectionLock) {
            if (!wanted || closed || socket != null) {
                return;
            }
        }
        Duration next = lastDelay.multipliedBy(2);
        next = next.compareTo(options.reconnectMax()) > 0 ? options.reconnectMax() : next;
        Opened opened;
        try {
            opened = open();
        } catch (RosException e) {
            scheduleReconnect(next);
            return;
        }
        String refused;
        synchronized (connectionLock) {
            if (!wanted || closed) {
                opened.socket().abort();
                return;
            }
            if (publish(opened) == null) {
                refused = null;
            } else if (refusal != null) {
                wanted = false;
                refused = refusal;
            } else {
                refused = "";
            }
        }
        if (refused == null) {
            LOG.log(System.Logger.Level.INFO, "reconnected to " + uri);
            events.opened();
        } else if (refused.isEmpty()) {
            scheduleReconnect(next);
        } else {
            events.error(new RosAuthException(refused));
        }
    }

    /**
     * Reads one WebSocket; the end of a stale socket is ignored by {@link #lost(WebSocket, String, Instant)}.
     * Every frame, pings and pongs included, tells the keepalive the server is alive.
     */
    private final class Listener implements WebSocket.Listener {
        private final StringBuilder partial = new StringBuilder();
        /** UTF-8 bytes of the text message being received. */
        private long partialBytes;
        /** Why this socket ended, once it has; guarded by {@link #connectionLock}. */
        private String endedBecause;

        @Override
        public void onOpen(WebSocket webSocket) {
            webSocket.request(1);
        }

        @Override
        public CompletionStage<?> onPing(WebSocket webSocket, ByteBuffer message) {
            keepalive.heard();
            received(message.remaining());
            sent(message.remaining()); // the pong
            webSocket.request(1);
            return null; // the JDK answers the ping with a pong itself
        }

        @Override
        public CompletionStage<?> onPong(WebSocket webSocket, ByteBuffer message) {
            keepalive.heard();
            received(message.remaining());
            webSocket.request(1);
            return null;
        }

        @Override
        public CompletionStage<?> onText(WebSocket webSocket, CharSequence data, boolean last) {
            keepalive.heard();
            partial.append(data);
            partialBytes += Traffic.utf8Length(data);
            if (last) {
                String text = partial.toString();
                partial.setLength(0);
                received(partialBytes);
                partialBytes = 0;
                events.received(text);
            }
            webSocket.request(1);
            return null;
        }

        @Override
        public CompletionStage<?> onBinary(WebSocket webSocket, ByteBuffer data, boolean last) {
            keepalive.heard();
            if (last) {
                received(data.remaining());
                events.error(new RosException("binary frame from " + uri + " ignored: this client speaks JSON only"
                        + " (do not request cbor compression)"));
            }
            webSocket.request(1);
            return null;
        }

        @Override
        public CompletionStage<?> onClose(WebSocket webSocket, int statusCode, String reason) {
            received(2 + Traffic.utf8Length(reason));
            String why = "closed by the server, code " + statusCode + (reason.isEmpty() ? "" : ": " + reason);
            synchronized (connectionLock) {
                endedBecause = why;
            }
            if (statusCode == Protocol.CLOSE_POLICY_VIOLATION
                    && reason.toLowerCase(Locale.ROOT).contains("authentication")) {
                refused(webSocket, reason);
            } else {
                lost(webSocket, why, Instant.now());
            }
            return null;
        }

        @Override
        public void onError(WebSocket webSocket, Throwable error) {
            String why = describe(error);
            synchronized (connectionLock) {
                endedBecause = why;
            }
            lost(webSocket, why, Instant.now());
        }
    }

    /** A WebSocket just opened, with the listener that knows whether it already ended. */
    private record Opened(WebSocket socket, Listener listener) {
    }
}
