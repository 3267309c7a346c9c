package caretaker.rosbridge;

/** Hears about the connection's life; every method has an empty default. */
public interface RosHandler {
    /** The connection is up (also after an automatic reconnect). */
    default void handleConnection() {
    }

    /** The connection went down; a reconnect follows unless {@link Ros#disconnect()} was called. */
    default void handleDisconnection() {
    }

    /**
     * Nothing came from the server for a few keepalive intervals (the connection is still up, and
     * is given up only after the ping timeout), or it came again.
     *
     * @param since when it was last heard, or null when it is heard again
     */
    default void handleQuiet(java.time.Instant since) {
    }

    /**
     * Something failed that no caller is waiting for (a malformed message, a callback that threw).
     *
     * @param error what failed
     */
    default void handleError(Throwable error) {
    }
}
