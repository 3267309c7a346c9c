package caretaker.pax;

import caretaker.sysrep.SysRep;
import java.util.Map;
import java.util.Set;

/** Carries out the commands of one SysRep on a system. */
public interface CommandPlugin extends AutoCloseable {
    /** @return the SysRep whose commands this plugin serves */
    SysRep sysRep();

    /** @return the ids of the commands this plugin serves (a subset of the SysRep's) */
    Set<String> commands();

    /**
     * Executes a command and waits for its real outcome.
     *
     * @param commandId one of {@link #commands()}
     * @param args every argument of the command, already checked and converted to its type
     *     (see {@link caretaker.sysrep.Command#checkArguments})
     * @return the outcome: failure carries the system's message
     * @throws PluginException the command could not be carried out for a reason outside the
     *     system (unknown command, connection lost, no answer in time)
     */
    CommandResult execute(String commandId, Map<String, Object> args);

    /** Releases subscriptions and threads; the connection itself belongs to the caller. */
    @Override
    void close();
}
