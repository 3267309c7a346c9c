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
 * @param quietSince while connected: when the server was last heard, if nothing came from it for a
 *        few keepalive intervals (null while it is heard, and while not connected)
 */
public record LinkState(URI rosbridge, boolean connected, Instant lostSince, int commandsInFlight,
        Instant quietSince) {
    /** @return "connected", "no news since T", or "link lost since T", with the commands in flight */
    @Override
    public String toString() {
        String inFlight = ", " + commandsInFlight + " command" + (commandsInFlight == 1 ? "" : "s") + " in flight";
        if (!connected) {
            return "link to " + rosbridge + " lost since " + lostSince + inFlight;
        }
        return quietSince == null ? "connected to " + rosbridge
                : "no news from " + rosbridge + " since " + quietSince + inFlight;
    }
}
