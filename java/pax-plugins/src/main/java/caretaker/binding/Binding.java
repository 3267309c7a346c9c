package caretaker.binding;

import java.util.List;

/**
 * A loaded binding file: the systems one robot offers to procedures.
 *
 * @param robot the robot's name, e.g. {@code iva}
 * @param systems the bound systems in file order
 * @param path the file
 */
public record Binding(String robot, List<SystemBinding> systems, String path) {
    /** Copies the list so the record stays immutable. */
    public Binding {
        systems = List.copyOf(systems);
    }
}
