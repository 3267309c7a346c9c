package caretaker.pax;

import java.util.List;
import java.util.Map;
import java.util.Set;
import java.util.concurrent.ConcurrentHashMap;
import java.util.concurrent.CopyOnWriteArrayList;

/**
 * The current values of a SysRep's telemetry items and their listeners: the shared state of every
 * telemetry plugin. Updating a value to what it already was notifies nobody. Thread-safe.
 */
public final class TelemetryBoard {
    private final String sysrepId;
    private final Map<String, TelemetryValue> values = new ConcurrentHashMap<>();
    private final List<TelemetryListener> listeners = new CopyOnWriteArrayList<>();
    private final System.Logger log = System.getLogger(TelemetryBoard.class.getName());

    /**
     * @param sysrepId the SysRep the items belong to
     * @param items the item ids, all starting unknown
     */
    public TelemetryBoard(String sysrepId, Set<String> items) {
        this.sysrepId = sysrepId;
        items.forEach(item -> values.put(item, TelemetryValue.unknown()));
    }

    /** @return the item ids */
    public Set<String> items() {
        return Set.copyOf(values.keySet());
    }

    /**
     * @param itemId an item
     * @return its value
     * @throws PluginException no such item
     */
    public TelemetryValue get(String itemId) {
        TelemetryValue value = values.get(itemId);
        if (value == null) {
            throw new PluginException("SysRep '" + sysrepId + "' has no telemetry item '" + itemId + "' (items: "
                    + String.join(", ", new java.util.TreeSet<>(values.keySet())) + ")");
        }
        return value;
    }

    /**
     * Sets a value and notifies listeners if value or staleness changed (not for a new timestamp
     * alone: a 5 Hz status topic would otherwise flood them).
     *
     * @param itemId an item
     * @param value its new value
     */
    public void put(String itemId, TelemetryValue value) {
        TelemetryValue old = values.put(itemId, value);
        if (old == null || old.stale() != value.stale() || !java.util.Objects.equals(old.value(), value.value())) {
            for (TelemetryListener listener : listeners) {
                try {
                    listener.telemetryChanged(sysrepId, itemId, value);
                } catch (RuntimeException e) {
                    log.log(System.Logger.Level.WARNING, "telemetry listener failed on " + sysrepId + "." + itemId, e);
                }
            }
        }
    }

    /** Marks every item stale, keeping the last values. */
    public void markAllStale() {
        for (String item : items()) {
            put(item, get(item).asStale());
        }
    }

    /** @param listener told about changes */
    public void addListener(TelemetryListener listener) {
        listeners.add(listener);
    }

    /** @param listener a listener added before */
    public void removeListener(TelemetryListener listener) {
        listeners.remove(listener);
    }
}
