package caretaker.binding;

import caretaker.rosbridge.LinkOptions;
import caretaker.rosbridge.RosAuth;
import caretaker.rosbridge.RosOptions;
import java.util.List;
import javax.net.ssl.SSLContext;

/**
 * A loaded binding file: the systems one robot offers to procedures, and how to reach them.
 *
 * @param robot the robot's name, e.g. {@code iva}
 * @param systems the bound systems in file order
 * @param path the file
 * @param link the link to the robot's rosbridge (delay, outage budget)
 * @param auth how the rosbridge connections authenticate, or null
 * @param tls whom {@code wss://} connections trust, or null for the JDK's default
 * @param linkStated the file states a {@code link:}: the robot is across a real link, so commands
 *     go only through the habitat's command ledger (exactly once, outcome learnt), never directly
 * @param ledgerNamespace the ROS namespace of the habitat's command ledger ("" = root)
 */
public record Binding(String robot, List<SystemBinding> systems, String path, LinkOptions link, RosAuth auth,
        SSLContext tls, boolean linkStated, String ledgerNamespace) {
    /** Copies the list so the record stays immutable. */
    public Binding {
        systems = List.copyOf(systems);
    }

    /** @return the options of this binding's rosbridge connections */
    public RosOptions rosOptions() {
        return RosOptions.defaults().withLink(link).withAuth(auth).withTls(tls);
    }
}
