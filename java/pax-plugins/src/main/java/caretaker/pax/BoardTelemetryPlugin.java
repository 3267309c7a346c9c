package caretaker.pax;

import caretaker.sysrep.SysRep;
import java.util.LinkedHashSet;
import java.util.Set;

/**
 * A telemetry plugin whose values live on a {@link TelemetryBoard} holding every telemetry item
 * of its SysRep: subclasses only put values on the board (and mark them stale); reading and
 * listening are served here, the same way for every such plugin.
 */
public abstract class BoardTelemetryPlugin implements TelemetryPlugin {
    /** The SysRep this plugin serves. */
    protected final SysRep sysRep;
    /** Current value of every telemetry item of {@link #sysRep}. */
    protected final TelemetryBoard board;

    /** @param sysRep the SysRep whose telemetry items the board holds */
    protected BoardTelemetryPlugin(SysRep sysRep) {
        this.sysRep = sysRep;
        Set<String> items = new LinkedHashSet<>();
        sysRep.telemetry().forEach(t -> items.add(t.id()));
        this.board = new TelemetryBoard(sysRep.id(), items);
    }

    @Override
    public SysRep sysRep() {
        return sysRep;
    }

    @Override
    public Set<String> items() {
        return board.items();
    }

    @Override
    public TelemetryValue value(String itemId) {
        return board.get(itemId);
    }

    @Override
    public void addListener(TelemetryListener listener) {
        board.addListener(listener);
    }

    @Override
    public void removeListener(TelemetryListener listener) {
        board.removeListener(listener);
    }
}
