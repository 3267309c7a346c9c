package caretaker.binding;

import caretaker.pax.PluginContext;
import caretaker.pax.PluginException;
import caretaker.pax.PluginOptions;
import caretaker.pax.at.AtCommandPlugin;
import caretaker.pax.at.AtTelemetryPlugin;
import caretaker.pax.convention.RosConventionPlugin;
import java.lang.reflect.InvocationTargetException;
import java.util.List;
import java.util.Set;
import java.util.function.Function;

/** The plugins a binding can name, and how a class name makes an integrator's own plugin. */
public enum PluginKind {
    /** The AT command plugin. */
    AT_COMMANDS("at_commands", AtCommandPlugin::new, AtCommandPlugin.OPTIONS),
    /** The AT telemetry plugin. */
    AT_TELEMETRY("at_telemetry", AtTelemetryPlugin::new, AtTelemetryPlugin.OPTIONS),
    /** The ROS-convention plugin (commands and telemetry). */
    ROS_CONVENTION("ros_convention", RosConventionPlugin::new, RosConventionPlugin.OPTIONS);

    private final String id;
    private final Function<PluginContext, AutoCloseable> factory;
    private final Set<String> options;

    PluginKind(String id, Function<PluginContext, AutoCloseable> factory, Set<String> options) {
        this.id = id;
        this.factory = factory;
        this.options = options;
    }

    /**
     * Checks a binding entry's options against what its plugins read, so a typo is an error
     * rather than a silently ignored setting. Entries with class-named plugins are not checked:
     * their options are the plugin's business.
     *
     * @param plugins the entry's plugin names
     * @param options the entry's options
     * @throws PluginException an option no plugin of the entry reads
     */
    public static void checkOptions(List<String> plugins, PluginOptions options) {
        Set<String> known = new java.util.HashSet<>();
        for (String name : plugins) {
            PluginKind kind = java.util.Arrays.stream(values()).filter(k -> k.id.equals(name)).findFirst().orElse(null);
            if (kind == null) {
                return;
            }
            known.addAll(kind.options);
        }
        options.requireKnown(String.join(" + ", plugins), known);
    }

    /** @return the name bindings use */
    public String id() {
        return id;
    }

    /** @return every built-in plugin name */
    public static List<String> names() {
        return java.util.Arrays.stream(values()).map(PluginKind::id).toList();
    }

    /**
     * Makes a plugin by built-in name or by class name.
     *
     * @param name {@code at_commands}, {@code at_telemetry}, {@code ros_convention}, or a fully
     *     qualified class with a public {@code (PluginContext)} constructor
     * @param context what the plugin is made from
     * @return the plugin (a CommandPlugin, a TelemetryPlugin, or both)
     * @throws PluginException the name is unknown or the plugin cannot be made
     */
    public static AutoCloseable create(String name, PluginContext context) {
        for (PluginKind kind : values()) {
            if (kind.id.equals(name)) {
                return kind.factory.apply(context);
            }
        }
        if (!name.contains(".")) {
            throw new PluginException(context.options().where() + ": unknown plugin '" + name + "' (built in: "
                    + String.join(", ", names()) + "; or give a class name)");
        }
        try {
            Object plugin = Class.forName(name).getConstructor(PluginContext.class).newInstance(context);
            if (!(plugin instanceof AutoCloseable closeable)) {
                throw new PluginException(context.options().where() + ": " + name
                        + " is not a CommandPlugin or TelemetryPlugin");
            }
            return closeable;
        } catch (InvocationTargetException e) {
            Throwable cause = e.getCause();
            throw cause instanceof RuntimeException runtime ? runtime
                    : new PluginException(context.options().where() + ": " + name + ": " + cause, cause);
        } catch (ReflectiveOperationException e) {
            throw new PluginException(context.options().where() + ": cannot make plugin " + name
                    + " (need a public constructor taking PluginContext): " + e, e);
        }
    }
}
