package caretaker.rosbridge;

import com.google.gson.JsonObject;
import com.google.gson.JsonParser;
import java.io.ByteArrayOutputStream;
import java.io.DataInputStream;
import java.io.IOException;
import java.io.InputStream;
import java.io.OutputStream;
import java.net.InetAddress;
import java.net.ServerSocket;
import java.net.Socket;
import java.net.URI;
import java.nio.charset.StandardCharsets;
import java.security.MessageDigest;
import java.security.NoSuchAlgorithmException;
import java.time.Duration;
import java.util.Base64;
import java.util.List;
import java.util.concurrent.BlockingQueue;
import java.util.concurrent.CountDownLatch;
import java.util.concurrent.LinkedBlockingQueue;
import java.util.concurrent.TimeUnit;
import java.util.concurrent.atomic.AtomicInteger;
import java.util.function.Function;
import javax.net.ssl.SSLContext;

/**
 * A minimal in-process WebSocket server (RFC 6455: handshake, masked client frames, text,
 * continuation, ping answered with pong, close) on 127.0.0.1, optionally over TLS, so the client's
 * JSON can be pinned without a ROS graph. Debian's Maven repository has no WebSocket server
 * library. One client at a time; every received message is queued, and an optional responder
 * answers messages as they arrive.
 */
public final class TestServer implements AutoCloseable {
    private static final String GUID = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11";

    private final ServerSocket listener;
    private final Thread acceptThread;
    private final BlockingQueue<JsonObject> received = new LinkedBlockingQueue<>();
    private final BlockingQueue<Socket> connections = new LinkedBlockingQueue<>();
    private volatile Function<JsonObject, List<JsonObject>> responder = message -> List.of();
    private volatile Socket client;
    private volatile OutputStream clientOut;
    private volatile CountDownLatch connected = new CountDownLatch(1);
    private final AtomicInteger handshakes = new AtomicInteger();
    private final AtomicInteger pings = new AtomicInteger();
    private volatile boolean answerPings = true;
    private final AtomicInteger unanswered = new AtomicInteger();
    private final String scheme;

    /** Starts listening on an ephemeral loopback port. */
    public TestServer() throws IOException {
        this(null);
    }

    /**
     * Starts listening on an ephemeral loopback port, over TLS when {@code tls} is given.
     *
     * @param tls the server's TLS context (its certificate), or null for plain ws://
     */
    public TestServer(SSLContext tls) throws IOException {
        listener = tls == null ? new ServerSocket(0, 50, InetAddress.getLoopbackAddress())
                : tls.getServerSocketFactory().createServerSocket(0, 50, InetAddress.getLoopbackAddress());
        scheme = tls == null ? "ws" : "wss";
        acceptThread = new Thread(this::acceptLoop, "test-websocket-server");
        acceptThread.setDaemon(true);
        acceptThread.start();
    }

    /** @return ws://127.0.0.1:PORT (wss:// over TLS) */
    public URI uri() {
        return URI.create(scheme + "://127.0.0.1:" + listener.getLocalPort());
    }

    /** @return the port listened on */
    public int port() {
        return listener.getLocalPort();
    }

    /** @return how many WebSocket handshakes the server answered so far */
    public int handshakes() {
        return handshakes.get();
    }

    /** @return how many pings the clients sent so far */
    public int pings() {
        return pings.get();
    }

    /** @param answer whether to answer pings with pongs (false: the server seems silent) */
    public void answerPings(boolean answer) {
        answerPings = answer;
    }

    /** @param responder returns the replies to each received message (runs on the reader thread) */
    public void respond(Function<JsonObject, List<JsonObject>> responder) {
        this.responder = responder;
    }

    /** @return the next message the client sent, waiting up to 5 s */
    public JsonObject next() throws InterruptedException {
        JsonObject message = received.poll(5, TimeUnit.SECONDS);
        if (message == null) {
            throw new AssertionError("the client sent nothing within 5 s");
        }
        return message;
    }

    /** @return the next message of the given op, skipping others, waiting up to 5 s in all */
    public JsonObject next(String op) throws InterruptedException {
        long deadline = System.nanoTime() + TimeUnit.SECONDS.toNanos(5);
        while (true) {
            JsonObject message = received.poll(deadline - System.nanoTime(), TimeUnit.NANOSECONDS);
            if (message == null) {
                throw new AssertionError("the client sent no " + op + " within 5 s");
            }
            if (op.equals(message.get("op").getAsString())) {
                return message;
            }
        }
    }

    /** @return a message if one arrives within {@code wait}, else null */
    public JsonObject poll(Duration wait) throws InterruptedException {
        return received.poll(wait.toMillis(), TimeUnit.MILLISECONDS);
    }

    /** Waits until a client has completed the handshake (again, after {@link #dropClient()}). */
    public void awaitClient() throws InterruptedException {
        if (!connected.await(10, TimeUnit.SECONDS)) {
            throw new AssertionError("no client connected within 10 s");
        }
    }

    /** Sends a text frame to the current client. */
    public synchronized void send(String text) throws IOException {
        byte[] payload = text.getBytes(StandardCharsets.UTF_8);
        OutputStream out = clientOut;
        out.write(0x81);
        if (payload.length < 126) {
            out.write(payload.length);
        } else if (payload.length < 65536) {
            out.write(126);
            out.write(payload.length >> 8);
            out.write(payload.length & 0xff);
        } else {
            out.write(127);
            for (int shift = 56; shift >= 0; shift -= 8) {
                out.write((int) ((long) payload.length >> shift) & 0xff);
            }
        }
        out.write(payload);
        out.flush();
    }

    /** Sends a JSON message to the current client. */
    public void send(JsonObject message) throws IOException {
        send(message.toString());
    }

    /**
     * Sends a close frame to the current client, then closes its connection.
     *
     * @param code the close code, e.g. 1008
     * @param reason the close reason
     */
    public synchronized void closeClient(int code, String reason) throws IOException {
        connected = new CountDownLatch(1);
        byte[] text = reason.getBytes(StandardCharsets.UTF_8);
        OutputStream out = clientOut;
        out.write(0x88);
        out.write(2 + text.length);
        out.write(code >> 8);
        out.write(code & 0xff);
        out.write(text);
        out.flush();
        client.close();
    }

    /** Closes the current client's TCP connection abruptly, as a crashing server would. */
    public void dropClient() throws IOException {
        connected = new CountDownLatch(1);
        Socket current = client;
        if (current != null) {
            current.close();
        }
    }

    private void acceptLoop() {
        while (!listener.isClosed()) {
            try {
                Socket socket = listener.accept();
                connections.add(socket);
                Thread reader = new Thread(() -> serve(socket), "test-websocket-client");
                reader.setDaemon(true);
                reader.start();
            } catch (IOException e) {
                return;
            }
        }
    }

    /**
     * Leaves the next {@code count} opening handshakes unanswered (the connection stays open, as a
     * starved server's would), as if the server were too slow to answer them.
     */
    public void leaveHandshakesUnanswered(int count) {
        unanswered.set(count);
    }

    private void serve(Socket socket) {
        try (socket) {
            InputStream in = socket.getInputStream();
            String key = handshake(in);
            if (unanswered.getAndUpdate(n -> Math.max(n - 1, 0)) > 0) {
                in.transferTo(OutputStream.nullOutputStream()); // until the client gives up on it
                return;
            }
            OutputStream out = socket.getOutputStream();
            // counted before the answer: a client that hears it may ask the count at once
            handshakes.incrementAndGet();
            String accept = Base64.getEncoder().encodeToString(MessageDigest.getInstance("SHA-1")
                    .digest((key + GUID).getBytes(StandardCharsets.US_ASCII)));
            out.write(("HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                    + "Sec-WebSocket-Accept: " + accept + "\r\n\r\n").getBytes(StandardCharsets.US_ASCII));
            out.flush();
            synchronized (this) {
                client = socket;
                clientOut = out;
            }
            connected.countDown();
            readFrames(new DataInputStream(in));
        } catch (IOException | NoSuchAlgorithmException e) {
            // The client went away or the test dropped it: nothing to serve any more.
        }
    }

    private static String handshake(InputStream in) throws IOException {
        ByteArrayOutputStream head = new ByteArrayOutputStream();
        int last4 = 0;
        while (last4 != 0x0d0a0d0a) {
            int b = in.read();
            if (b < 0) {
                throw new IOException("closed during handshake");
            }
            head.write(b);
            last4 = (last4 << 8) | b;
        }
        for (String line : head.toString(StandardCharsets.US_ASCII).split("\r\n")) {
            int colon = line.indexOf(':');
            if (colon > 0 && line.substring(0, colon).trim().equalsIgnoreCase("Sec-WebSocket-Key")) {
                return line.substring(colon + 1).trim();
            }
        }
        throw new IOException("no Sec-WebSocket-Key in handshake");
    }

    private void readFrames(DataInputStream in) throws IOException {
        ByteArrayOutputStream message = new ByteArrayOutputStream();
        while (true) {
            int first = in.readUnsignedByte();
            int second = in.readUnsignedByte();
            boolean fin = (first & 0x80) != 0;
            int opcode = first & 0x0f;
            long length = second & 0x7f;
            if (length == 126) {
                length = in.readUnsignedShort();
            } else if (length == 127) {
                length = in.readLong();
            }
            byte[] mask = new byte[4];
            if ((second & 0x80) != 0) {
                in.readFully(mask);
            }
            byte[] payload = new byte[(int) length];
            in.readFully(payload);
            for (int i = 0; i < payload.length; i++) {
                payload[i] ^= mask[i % 4];
            }
            if (opcode == 0x8) {
                return;
            }
            if (opcode == 0x9) {
                pings.incrementAndGet();
                if (answerPings) {
                    pong(payload);
                }
                continue;
            }
            if (opcode == 0xA) {
                continue;
            }
            message.write(payload);
            if (fin) {
                JsonObject json = JsonParser.parseString(message.toString(StandardCharsets.UTF_8)).getAsJsonObject();
                message.reset();
                received.add(json);
                for (JsonObject reply : responder.apply(json)) {
                    send(reply);
                }
            }
        }
    }

    private synchronized void pong(byte[] payload) throws IOException {
        OutputStream out = clientOut;
        out.write(0x8A);
        out.write(payload.length);
        out.write(payload);
        out.flush();
    }

    @Override
    public void close() throws IOException {
        listener.close();
        for (Socket socket : connections) {
            socket.close();
        }
    }
}
