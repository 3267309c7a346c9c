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

    /**
     * Stops the command {@code key} now if it still runs (an operator's halt). Called from another
     * thread while {@link #execute} waits; that {@code execute} then returns its real outcome: a
     * failure or {@link Outcome#HALTED} when the cancel stopped it, success when it had finished
     * first. Goes to the system directly, not through the command ledger; safe to call twice, and
     * for a key that already ended. Blocks at most the plugin's call timeout (plus the time the
     * link takes to come back within its outage budget).
     *
     * @param key the command to stop
     * @return what the system said; {@code stopped == false} when this plugin's commands cannot
     *     be cancelled or the cancel did not reach the system
     */
    CancelResult cancel(CommandKey key);

    /** Releases subscriptions and threads; the connection itself belongs to the caller. */
    @Override
    void close();
}
