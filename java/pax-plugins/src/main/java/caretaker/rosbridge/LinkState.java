package caretaker.rosbridge;

import java.net.URI;
import java.time.Instant;

/**
 * The state of the link to one rosbridge server, as commands see it.
 *
 * @param rosbridge the server
 * @param connected whether the connection is up
 * @param lostSince when it was lost (null while connected)
 * @param commandsInFlight commands sent or waiting to be sent whose outcome is not known yet
 */
public record LinkState(URI rosbridge, boolean connected, Instant lostSince, int commandsInFlight) {
    /** @return "connected", or "link lost since T, N commands in flight" */
    @Override
    public String toString() {
        return connected ? "connected to " + rosbridge
                : "link to " + rosbridge + " lost since " + lostSince + ", " + commandsInFlight + " command"
                        + (commandsInFlight == 1 ? "" : "s") + " in flight";
    }
}
