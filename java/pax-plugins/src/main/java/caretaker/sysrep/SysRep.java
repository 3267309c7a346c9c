package caretaker.sysrep;

import java.util.List;

/**
 * One loaded SysRep file.
 *
 * @param id the SysRep id procedures name
 * @param name the human-readable name
 * @param commands the commands in file order
 * @param telemetry the telemetry items in file order
 * @param path the file it was loaded from ("" if built in code)
 * @param description free text, or null
 * @param version the file's version, or null
 */
public record SysRep(String id, String name, List<Command> commands, List<Telemetry> telemetry, String path,
        String description, String version) {
    /** Copies the lists so the record stays immutable. */
    public SysRep {
        commands = List.copyOf(commands);
        telemetry = List.copyOf(telemetry);
    }

    /**
     * @param commandId a command id
     * @return the command, or null
     */
    public Command command(String commandId) {
        return commands.stream().filter(c -> c.id().equals(commandId)).findFirst().orElse(null);
    }

    /**
     * @param itemId a telemetry id
     * @return the item, or null
     */
    public Telemetry telemetryItem(String itemId) {
        return telemetry.stream().filter(t -> t.id().equals(itemId)).findFirst().orElse(null);
    }
}
