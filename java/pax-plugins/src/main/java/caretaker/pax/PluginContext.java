package caretaker.pax;

import caretaker.rosbridge.CommandLedger;
import caretaker.rosbridge.Ros;
import caretaker.sysrep.SysRep;

/**
 * What a plugin is made from: the SysRep it serves, the rosbridge connection of its robot, the
 * command ledger on that connection, the ROS namespace of the system and the binding's options.
 * Plugins made by name from a binding have a public constructor taking this.
 *
 * @param sysRep the SysRep to serve
 * @param ros the robot's rosbridge connection (owned by the caller, not the plugin)
 * @param ledger sends state-changing commands on {@code ros} at most once (owned by the caller)
 * @param namespace the ROS namespace of the system, e.g. {@code /cdra} ("" = root)
 * @param options plugin-specific options
 */
public record PluginContext(SysRep sysRep, Ros ros, CommandLedger ledger, String namespace, PluginOptions options) {
    /**
     * @param name a relative ROS name
     * @return it resolved in {@link #namespace()}, e.g. {@code /cdra/unlock_filter}
     */
    public String resolve(String name) {
        String base = namespace.endsWith("/") ? namespace.substring(0, namespace.length() - 1) : namespace;
        return (base.startsWith("/") || base.isEmpty() ? base : "/" + base) + "/" + name;
    }
}
