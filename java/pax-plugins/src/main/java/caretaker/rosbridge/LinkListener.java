package caretaker.rosbridge;

/** Hears about the link's state: connected, or lost since T with N commands in flight. */
@FunctionalInterface
public interface LinkListener {
    /**
     * Called on the connection's callback thread when the link goes down or up, and while it is
     * down whenever the number of commands in flight changes. Must return quickly.
     *
     * @param state the new state
     */
    void linkChanged(LinkState state);
}
