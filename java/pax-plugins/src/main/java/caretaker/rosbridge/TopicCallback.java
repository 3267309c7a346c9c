package caretaker.rosbridge;

/** Receives the messages of a subscription. */
@FunctionalInterface
public interface TopicCallback {
    /**
     * Called on the connection's callback thread, in arrival order.
     *
     * @param message the message received
     */
    void handleMessage(Message message);
}
