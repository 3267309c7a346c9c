package caretaker.binding;

import caretaker.pax.CancelResult;
import caretaker.pax.CommandKey;
import caretaker.pax.CommandPlugin;
import caretaker.pax.CommandResult;
import caretaker.pax.Outcome;
import caretaker.pax.PluginContext;
import caretaker.pax.PluginException;
import caretaker.pax.TelemetryListener;
import caretaker.pax.TelemetryPlugin;
import caretaker.pax.TelemetryValue;
import caretaker.rosbridge.CommandLedger;
import caretaker.rosbridge.LedgerMissingException;
import caretaker.rosbridge.LinkListener;
import caretaker.rosbridge.LinkState;
import caretaker.rosbridge.Ros;
import caretaker.rosbridge.RosAuthException;
import caretaker.rosbridge.RosException;
import caretaker.rosbridge.Traffic;
import caretaker.sysrep.Command;
import caretaker.sysrep.SysRep;
import java.net.URI;
import java.nio.file.Path;
import java.util.ArrayList;
import java.util.LinkedHashMap;
import java.util.List;
import java.util.Map;
import java.util.Set;
import java.util.concurrent.ConcurrentHashMap;

/**
 * The plugins of one binding, ready to use: what a procedure executive talks to. Opens one
 * rosbridge connection per server named in the binding (kept up across drops, with the binding's
 * link and security settings) and a {@link CommandLedger} on each, makes the plugins, checks and
 * converts command arguments against the SysRep before a plugin sees them.
 *
 * <pre>
 * try (PaxHost host = PaxHost.open(Path.of("sysrep/bindings/iva.yaml"), null)) {
 *     CommandResult r = host.execute(CommandKey.parse("run-1/1.1/1"), "cdra", "unlock_filter", Map.of());
 *     TelemetryValue locked = host.telemetry("cdra", "filter_locked");
 * }
 * </pre>
 */
public final class PaxHost implements AutoCloseable {
    private final Binding binding;
    private final List<Ros> connections = new ArrayList<>();
    private final List<CommandLedger> ledgers = new ArrayList<>();
    private final List<AutoCloseable> plugins = new ArrayList<>();
    private final Map<String, SysRep> sysReps = new LinkedHashMap<>();
    /** sysrep id → command id → plugin. */
    private final Map<String, Map<String, CommandPlugin>> commandPlugins = new LinkedHashMap<>();
    /** sysrep id → item id → plugin. */
    private final Map<String, Map<String, TelemetryPlugin>> telemetryPlugins = new LinkedHashMap<>();
    /** Commands whose outcome is not known yet (running, or UNKNOWN) → the plugin that sent them. */
    private final Map<CommandKey, CommandPlugin> sentBy = new ConcurrentHashMap<>();
    /** Keys a cancel was sent for while they ran. */
    private final Set<CommandKey> cancelled = ConcurrentHashMap.newKeySet();

    private PaxHost(Binding binding) {
        this.binding = binding;
    }

    /**
     * Loads a binding, connects to its rosbridge servers and makes its plugins.
     *
     * @param bindingFile the binding file
     * @param rosbridgeOverride replaces every rosbridge URL of the binding, or null
     * @return the host; close it when done
     * @throws BindingException the binding is wrong
     * @throws caretaker.sysrep.SysRepException a SysRep is invalid
     * @throws PluginException a plugin cannot be made (bad option, SysRep does not fit)
     * @throws RosException a rosbridge server cannot be reached or refuses the authentication
     * @throws LedgerMissingException the binding states a link and the habitat has no command ledger
     */
    public static PaxHost open(Path bindingFile, URI rosbridgeOverride) {
        Binding binding = BindingLoader.load(bindingFile, rosbridgeOverride);
        PaxHost host = new PaxHost(binding);
        try {
            host.start();
        } catch (RuntimeException e) {
            host.close();
            throw e;
        }
        return host;
    }

    private void start() {
        Map<URI, Ros> byUri = new LinkedHashMap<>();
        Map<Ros, CommandLedger> ledgerOf = new LinkedHashMap<>();
        for (SystemBinding system : binding.systems()) {
            Ros ros = byUri.get(system.rosbridge());
            if (ros == null) {
                ros = new Ros(system.rosbridge(), binding.rosOptions());
                connections.add(ros);
                byUri.put(system.rosbridge(), ros);
                CommandLedger ledger = new CommandLedger(ros, binding.link(), binding.linkStated(),
                        binding.ledgerNamespace());
                ledgers.add(ledger);
                ledgerOf.put(ros, ledger);
                connect(system, ros, ledger);
            }
            SysRep sysRep = system.sysRep();
            sysReps.put(sysRep.id(), sysRep);
            Map<String, CommandPlugin> commands = commandPlugins.computeIfAbsent(sysRep.id(),
                    k -> new LinkedHashMap<>());
            Map<String, TelemetryPlugin> items = telemetryPlugins.computeIfAbsent(sysRep.id(),
                    k -> new LinkedHashMap<>());
            for (String name : system.plugins()) {
                AutoCloseable plugin = PluginKind.create(name, new PluginContext(sysRep, ros, ledgerOf.get(ros),
                        system.namespace(), system.options()));
                plugins.add(plugin);
                if (plugin instanceof CommandPlugin commandPlugin) {
                    commandPlugin.commands().forEach(c -> commands.put(c, commandPlugin));
                }
                if (plugin instanceof TelemetryPlugin telemetryPlugin) {
                    telemetryPlugin.items().forEach(i -> items.put(i, telemetryPlugin));
                }
            }
        }
    }

    /**
     * Connects and asks for the habitat's command ledger at once, so that a refused authentication
     * fails the open rather than the first command; a slow answer is only logged (the first
     * command asks again).
     */
    private static void connect(SystemBinding system, Ros ros, CommandLedger ledger) {
        try {
            ros.connect(ledger.link().outageBudget()); // a slow habitat (a starved CPU, a far link) is not a dead one
        } catch (RosAuthException e) {
            throw new RosAuthException(system.where() + ": " + e.getMessage());
        } catch (RosException e) {
            throw new RosException(system.where() + ": " + e.getMessage()
                    + " (is the robot's rosbridge server running? `caretaker bridge`)", e);
        }
        try {
            ledger.probe(ros.getOptions().timeout());
        } catch (RosAuthException e) {
            throw new RosAuthException(system.where() + ": " + e.getMessage());
        } catch (LedgerMissingException e) {
            throw new LedgerMissingException(system.where() + ": this binding states a link: " + e.getMessage());
        } catch (RosException e) {
            System.getLogger(PaxHost.class.getName()).log(System.Logger.Level.WARNING, system.where()
                    + ": the command ledger did not answer yet: " + e.getMessage());
        }
    }

    /** @return the binding this host serves */
    public Binding binding() {
        return binding;
    }

    /** @return the bound SysReps in binding order */
    public List<SysRep> sysReps() {
        return List.copyOf(sysReps.values());
    }

    /**
     * Checks and converts the arguments against the SysRep, then executes the command and waits
     * for its real outcome. Never reports success or failure the system did not report: an
     * outcome that cannot be learnt is {@link caretaker.pax.Outcome#UNKNOWN}. A command that
     * {@link #cancel} stopped and that did not succeed is {@link Outcome#HALTED}, with the
     * system's message; one that succeeded before the cancel reached it stays SUCCEEDED.
     *
     * @param key the command's key; the same key is the same command, executed at most once
     * @param sysrepId a bound SysRep
     * @param commandId one of its commands
     * @param args argument name → value (strings are accepted for every type)
     * @return the system's outcome
     * @throws PluginException unknown SysRep or command, no plugin serves it, or bad arguments
     */
    public CommandResult execute(CommandKey key, String sysrepId, String commandId, Map<String, ?> args) {
        SysRep sysRep = sysRep(sysrepId);
        Command command = sysRep.command(commandId);
        if (command == null) {
            throw new PluginException("SysRep '" + sysrepId + "' has no command '" + commandId + "' (commands: "
                    + String.join(", ", sysRep.commands().stream().map(Command::id).toList()) + ")");
        }
        CommandPlugin plugin = commandPlugins.get(sysrepId).get(commandId);
        if (plugin == null) {
            throw new PluginException("no plugin serves command '" + commandId + "' of SysRep '" + sysrepId
                    + "' in " + binding.path());
        }
        Map<String, Object> typed;
        try {
            typed = command.checkArguments(args);
        } catch (IllegalArgumentException e) {
            throw new PluginException(sysrepId + "." + e.getMessage(), e);
        }
        sentBy.put(key, plugin);
        CommandResult result;
        try {
            result = plugin.execute(key, commandId, typed);
        } catch (RuntimeException e) {
            sentBy.remove(key);
            cancelled.remove(key);
            throw e;
        }
        boolean halted = cancelled.remove(key) && result.outcome() == Outcome.FAILED;
        if (result.outcome() != Outcome.UNKNOWN) {
            sentBy.remove(key); // an UNKNOWN one may still run on the robot: it stays cancellable
        }
        return halted ? new CommandResult(Outcome.HALTED, result.message(), result.values()) : result;
    }

    /**
     * Stops command {@code key} if it still runs: the plugin that sent it cancels it on the system
     * directly (not through the command ledger). Safe to call twice and for a key that ended.
     *
     * @param key a command sent through this host
     * @return what the system said, or that no command of that key is running here
     */
    public CancelResult cancel(CommandKey key) {
        CommandPlugin plugin = sentBy.get(key);
        if (plugin == null) {
            return new CancelResult(false, "no command " + key + " is running here: nothing to cancel");
        }
        cancelled.add(key);
        return plugin.cancel(key);
    }

    /**
     * @param sysrepId a bound SysRep
     * @param itemId one of its telemetry items
     * @return the item's current value, timestamp and staleness
     * @throws PluginException unknown SysRep or item, or no plugin serves it
     */
    public TelemetryValue telemetry(String sysrepId, String itemId) {
        SysRep sysRep = sysRep(sysrepId);
        if (sysRep.telemetryItem(itemId) == null) {
            throw new PluginException("SysRep '" + sysrepId + "' has no telemetry item '" + itemId + "' (items: "
                    + String.join(", ", sysRep.telemetry().stream().map(t -> t.id()).toList()) + ")");
        }
        TelemetryPlugin plugin = telemetryPlugins.get(sysrepId).get(itemId);
        if (plugin == null) {
            throw new PluginException("no plugin serves telemetry '" + itemId + "' of SysRep '" + sysrepId + "' in "
                    + binding.path());
        }
        return plugin.value(itemId);
    }

    /** @param listener told about every telemetry change of every bound SysRep */
    public void addListener(TelemetryListener listener) {
        for (AutoCloseable plugin : plugins) {
            if (plugin instanceof TelemetryPlugin telemetryPlugin) {
                telemetryPlugin.addListener(listener);
            }
        }
    }

    /** @param listener a listener added before */
    public void removeListener(TelemetryListener listener) {
        for (AutoCloseable plugin : plugins) {
            if (plugin instanceof TelemetryPlugin telemetryPlugin) {
                telemetryPlugin.removeListener(listener);
            }
        }
    }

    /**
     * @param listener told when a robot link goes down or up, and while down when the number of
     *     commands in flight changes (on a connection's callback thread; return quickly)
     */
    public void addLinkListener(LinkListener listener) {
        ledgers.forEach(ledger -> ledger.addLinkListener(listener));
    }

    /** @param listener a listener added before */
    public void removeLinkListener(LinkListener listener) {
        ledgers.forEach(ledger -> ledger.removeLinkListener(listener));
    }

    /** @return what each rosbridge connection carried so far, in binding order */
    public List<Traffic> traffic() {
        return connections.stream().map(Ros::traffic).toList();
    }

    /** @return the state of each robot link, in binding order */
    public List<LinkState> linkStates() {
        return ledgers.stream().map(CommandLedger::linkState).toList();
    }

    private SysRep sysRep(String sysrepId) {
        SysRep sysRep = sysReps.get(sysrepId);
        if (sysRep == null) {
            throw new PluginException("SysRep '" + sysrepId + "' is not bound in " + binding.path() + " (bound: "
                    + String.join(", ", sysReps.keySet()) + ")");
        }
        return sysRep;
    }

    /** Closes every plugin, then every connection. */
    @Override
    public void close() {
        for (AutoCloseable plugin : plugins) {
            try {
                plugin.close();
            } catch (Exception e) {
                System.getLogger(PaxHost.class.getName()).log(System.Logger.Level.WARNING, "closing a plugin failed",
                        e);
            }
        }
        ledgers.forEach(CommandLedger::close);
        connections.forEach(Ros::close);
    }
}
