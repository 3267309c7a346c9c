package caretaker.pax;

import caretaker.sysrep.SysRep;
import java.util.Set;

/** Reports the telemetry of one SysRep from a system. */
public interface TelemetryPlugin extends AutoCloseable {
    /** @return the SysRep whose telemetry this plugin serves */
    SysRep sysRep();

    /** @return the ids of the telemetry items this plugin serves */
    Set<String> items();

    /**
     * @param itemId one of {@link #items()}
     * @return its current value, timestamp and staleness
     * @throws PluginException the item is not served here
     */
    TelemetryValue value(String itemId);

    /** @param listener told about every change of value or staleness */
    void addListener(TelemetryListener listener);

    /** @param listener a listener added before; no effect otherwise */
    void removeListener(TelemetryListener listener);

    /** Stops listening to the system. */
    @Override
    void close();
}
