package caretaker.pax;

import caretaker.sysrep.SysRep;
import java.util.Map;
import java.util.Set;

/**
 * Carries out the commands of one SysRep on a system.
 *
 * <p>The contract: a plugin never reports success or failure it did not learn from the system.
 * When a command may have been executed but its outcome cannot be learnt (the link dropped and
 * did not come back within its outage budget, the habitat restarted), the result is
 * {@link Outcome#UNKNOWN} with the reason. A state-changing command goes through the habitat's
 * command ledger ({@link PluginContext#ledger()}) with its {@link CommandKey}, so it is executed
 * at most once however often the link makes the plugin send it.
 */
public interface CommandPlugin extends AutoCloseable {
    /** @return the SysRep whose commands this plugin serves */
    SysRep sysRep();

    /** @return the ids of the commands this plugin serves (a subset of the SysRep's) */
    Set<String> commands();

    /**
     * Executes a command and waits for its real outcome.
     *
     * @param key identifies this command; the same key is the same command (sent at most once)
     * @param commandId one of {@link #commands()}
     * @param args every argument of the command, already checked and converted to its type
     *     (see {@link caretaker.sysrep.Command#checkArguments})
     * @return the outcome: failure carries the system's message, unknown the reason
     * @throws PluginException the command does not exist here (nothing was sent)
     */
    CommandResult execute(CommandKey key, String commandId, Map<String, Object> args);

    /** Releases subscriptions and threads; the connection itself belongs to the caller. */
    @Override
    void close();
}
