package caretaker.binding;

import caretaker.pax.PluginOptions;
import caretaker.sysrep.SysRep;
import java.net.URI;
import java.util.List;

/**
 * One entry of a binding: a SysRep, the plugins serving it, and where they reach the system.
 *
 * @param sysRep the SysRep
 * @param plugins plugin names ({@code at_commands}, {@code at_telemetry}, {@code ros_convention})
 *     or fully qualified class names of plugins with a {@code (PluginContext)} constructor
 * @param rosbridge the rosbridge server of the robot
 * @param namespace the system's ROS namespace
 * @param options plugin options
 * @param where this entry in its file, for messages
 */
public record SystemBinding(SysRep sysRep, List<String> plugins, URI rosbridge, String namespace,
        PluginOptions options, String where) {
    /** Copies the plugin list so the record stays immutable. */
    public SystemBinding {
        plugins = List.copyOf(plugins);
    }
}
