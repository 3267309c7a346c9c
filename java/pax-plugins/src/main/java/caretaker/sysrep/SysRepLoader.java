package caretaker.sysrep;

import java.io.IOException;
import java.math.BigInteger;
import java.nio.charset.StandardCharsets;
import java.nio.file.DirectoryStream;
import java.nio.file.Files;
import java.nio.file.NoSuchFileException;
import java.nio.file.Path;
import java.util.ArrayList;
import java.util.LinkedHashMap;
import java.util.List;
import java.util.Map;
import java.util.Set;
import java.util.TreeSet;
import java.util.function.BiFunction;
import java.util.regex.Pattern;
import org.yaml.snakeyaml.LoaderOptions;
import org.yaml.snakeyaml.Yaml;
import org.yaml.snakeyaml.constructor.SafeConstructor;
import org.yaml.snakeyaml.error.MarkedYAMLException;
import org.yaml.snakeyaml.error.YAMLException;
import org.yaml.snakeyaml.nodes.MappingNode;
import org.yaml.snakeyaml.nodes.Node;
import org.yaml.snakeyaml.nodes.NodeTuple;
import org.yaml.snakeyaml.nodes.ScalarNode;
import org.yaml.snakeyaml.nodes.SequenceNode;
import org.yaml.snakeyaml.nodes.Tag;

/**
 * Loads and validates SysRep files. Walks the YAML node tree (not plain maps) so every error can
 * name its line; the checks and their order are those of {@code procedure_language.sysrep._Reader}, so both
 * loaders report the same first error with the same text.
 */
public final class SysRepLoader {
    private static final Pattern IDENTIFIER = Pattern.compile("^[A-Za-z_][A-Za-z0-9_]*$");
    private static final Set<String> TOP_LEVEL_KEYS = Set.of("id", "name", "commands", "telemetry", "description",
            "version");
    private static final Set<String> VALUE_EXTENSIONS = Set.of("units", "min", "max", "enum", "description");
    /** A telemetry item may also state its limits (see {@link Limits}). */
    private static final Set<String> TELEMETRY_EXTENSIONS = Set.of("units", "min", "max", "enum", "description",
            "limits");
    private static final Set<String> COMMAND_EXTENSIONS = Set.of("hazardous", "description");

    private final String path;

    private SysRepLoader(String path) {
        this.path = path;
    }

    /**
     * Loads and validates one SysRep file.
     *
     * @param file the file
     * @return the SysRep
     * @throws SysRepException the file is missing, not YAML, or not a valid SysRep; the message
     *     names the file, the line, the entry and what is wrong
     */
    public static SysRep load(Path file) {
        String path = file.toString();
        String text;
        try {
            text = Files.readString(file, StandardCharsets.UTF_8);
        } catch (NoSuchFileException e) {
            throw new SysRepException(path, 0, "", "cannot read: No such file or directory");
        } catch (IOException e) {
            throw new SysRepException(path, 0, "", "cannot read: " + e.getMessage());
        }
        Node root;
        try {
            root = new Yaml(new SafeConstructor(new LoaderOptions())).compose(new java.io.StringReader(text));
        } catch (MarkedYAMLException e) {
            int line = e.getProblemMark() != null ? e.getProblemMark().getLine() + 1 : 0;
            String problem = e.getProblem() != null ? e.getProblem() : e.getMessage();
            throw new SysRepException(path, line, "", "not valid YAML: " + problem);
        } catch (YAMLException e) {
            throw new SysRepException(path, 0, "", "not valid YAML: " + e.getMessage());
        }
        return new SysRepLoader(path).sysrep(root);
    }

    /**
     * Loads every {@code *.yaml} directly in a directory (not subfolders), keyed by SysRep id.
     *
     * @param directory the directory
     * @return id → SysRep, in file-name order
     * @throws SysRepException a file is invalid, or two files declare the same id
     */
    public static Map<String, SysRep> loadDirectory(Path directory) {
        TreeSet<Path> files = new TreeSet<>();
        try (DirectoryStream<Path> stream = Files.newDirectoryStream(directory, "*.yaml")) {
            stream.forEach(files::add);
        } catch (IOException e) {
            throw new SysRepException(directory.toString(), 0, "", "cannot read directory: " + e.getMessage());
        }
        Map<String, SysRep> sysreps = new LinkedHashMap<>();
        for (Path file : files) {
            SysRep sysrep = load(file);
            if (sysreps.containsKey(sysrep.id())) {
                throw new SysRepException(file.toString(), 0, "id", "duplicate SysRep id " + PyRepr.of(sysrep.id())
                        + " (also in " + sysreps.get(sysrep.id()).path() + ")");
            }
            sysreps.put(sysrep.id(), sysrep);
        }
        return sysreps;
    }

    private SysRepException fail(Node node, String where, String problem) {
        int line = node != null ? node.getStartMark().getLine() + 1 : 0;
        return new SysRepException(path, line, where, problem);
    }

    private String scalar(Node node, String where, String what) {
        if (!(node instanceof ScalarNode scalar) || !Tag.STR.equals(node.getTag())) {
            throw fail(node, where, what + " must be a string, got " + describe(node));
        }
        return scalar.getValue();
    }

    private String identifier(Node node, String where, String what) {
        String value = scalar(node, where, what);
        if (!IDENTIFIER.matcher(value).matches()) {
            throw fail(node, where, what + " " + PyRepr.of(value) + " is not an identifier (letters, digits, _)");
        }
        return value;
    }

    private ValueType typeName(Node node, String where) {
        String value = scalar(node, where, "type");
        ValueType type = ValueType.byId(value);
        if (type == null) {
            throw fail(node, where, "unknown type " + PyRepr.of(value) + " (expected one of " + ValueType.allIds()
                    + ")");
        }
        return type;
    }

    private Map<String, Object> extensions(Node node, String where, Set<String> allowed) {
        if (!(node instanceof MappingNode)) {
            throw fail(node, where, "extension must be a mapping, got " + describe(node));
        }
        Map<?, ?> raw = (Map<?, ?>) NodeValues.of(node);
        String allowedText = String.join(", ", new TreeSet<>(allowed));
        Map<String, Object> data = new LinkedHashMap<>();
        for (Map.Entry<?, ?> entry : raw.entrySet()) {
            if (!(entry.getKey() instanceof String key) || !allowed.contains(key)) {
                throw fail(node, where, "unknown extension " + PyRepr.of(entry.getKey()) + " (allowed: " + allowedText
                        + ")");
            }
            data.put(key, entry.getValue());
        }
        for (String key : List.of("min", "max")) {
            if (data.containsKey(key) && (!(data.get(key) instanceof Number))) {
                throw fail(node, where, "extension " + PyRepr.of(key) + " must be a number, got "
                        + PyRepr.of(data.get(key)));
            }
        }
        if (data.containsKey("enum") && !(data.get("enum") instanceof List<?>)) {
            throw fail(node, where, "extension 'enum' must be a list, got " + PyRepr.of(data.get("enum")));
        }
        if (data.containsKey("hazardous") && !(data.get("hazardous") instanceof Boolean)) {
            throw fail(node, where, "extension 'hazardous' must be true or false, got "
                    + PyRepr.of(data.get("hazardous")));
        }
        for (String key : List.of("units", "description")) {
            if (data.containsKey(key) && !(data.get(key) instanceof String)) {
                throw fail(node, where, "extension " + PyRepr.of(key) + " must be a string, got "
                        + PyRepr.of(data.get(key)));
            }
        }
        return data;
    }

    private Map<String, Object> valueExtensions(Node node, String where, ValueType type) {
        return valueExtensions(node, where, type, VALUE_EXTENSIONS);
    }

    private Map<String, Object> valueExtensions(Node node, String where, ValueType type, Set<String> allowed) {
        Map<String, Object> data = extensions(node, where, allowed);
        if ((data.containsKey("min") || data.containsKey("max")) && !type.isNumeric()) {
            throw fail(node, where, "min/max apply to integer or real, not " + type.id());
        }
        if (data.containsKey("enum")) {
            List<Object> values = new ArrayList<>();
            try {
                for (Object value : (List<?>) data.get("enum")) {
                    values.add(type.check("enum", value));
                }
            } catch (IllegalArgumentException e) {
                throw fail(node, where, "enum value does not match type " + type.id() + ": " + e.getMessage());
            }
            data.put("enum", values);
        }
        return data;
    }

    @SuppressWarnings("unchecked")
    private static List<Object> allowedValues(Map<String, Object> ext) {
        return (List<Object>) ext.get("enum");
    }

    private Argument argument(Node node, String where) {
        if (!(node instanceof SequenceNode sequence) || !(sequence.getValue().size() == 2
                || sequence.getValue().size() == 3)) {
            throw fail(node, where, "argument must be [name, type] or [name, type, {extensions}], got "
                    + describe(node));
        }
        List<Node> items = sequence.getValue();
        String name = identifier(items.get(0), where, "argument name");
        String at = where + " " + PyRepr.of(name);
        ValueType type = typeName(items.get(1), at);
        Map<String, Object> ext = items.size() == 3 ? valueExtensions(items.get(2), at, type) : Map.of();
        return new Argument(name, type, (String) ext.get("units"), (Number) ext.get("min"), (Number) ext.get("max"),
                allowedValues(ext), (String) ext.get("description"));
    }

    private Command command(Node node, int index) {
        String where = "commands[" + index + "]";
        if (!(node instanceof SequenceNode sequence) || !(sequence.getValue().size() == 3
                || sequence.getValue().size() == 4)) {
            throw fail(node, where, "command must be [id, label, [[arg, type], ...]] (3 or 4 items), got "
                    + describe(node));
        }
        List<Node> items = sequence.getValue();
        String commandId = identifier(items.get(0), where, "command id");
        where = where + " " + PyRepr.of(commandId);
        String label = scalar(items.get(1), where, "label");
        Node argsNode = items.get(2);
        if (!(argsNode instanceof SequenceNode argsSequence)) {
            throw fail(argsNode, where, "arguments must be a list of [name, type], got " + describe(argsNode));
        }
        List<Argument> args = new ArrayList<>();
        int number = 1;
        for (Node argNode : argsSequence.getValue()) {
            Argument arg = argument(argNode, where + " argument " + number++);
            if (args.stream().anyMatch(a -> a.name().equals(arg.name()))) {
                throw fail(argNode, where, "duplicate argument " + PyRepr.of(arg.name()));
            }
            args.add(arg);
        }
        Map<String, Object> ext = items.size() == 4 ? extensions(items.get(3), where, COMMAND_EXTENSIONS) : Map.of();
        return new Command(commandId, label, args, Boolean.TRUE.equals(ext.get("hazardous")),
                (String) ext.get("description"), node.getStartMark().getLine() + 1);
    }

    private Telemetry telemetry(Node node, int index) {
        String where = "telemetry[" + index + "]";
        if (!(node instanceof SequenceNode sequence) || !(sequence.getValue().size() == 3
                || sequence.getValue().size() == 4)) {
            throw fail(node, where, "telemetry must be [id, label, type] (3 or 4 items), got " + describe(node));
        }
        List<Node> items = sequence.getValue();
        String itemId = identifier(items.get(0), where, "telemetry id");
        where = where + " " + PyRepr.of(itemId);
        String label = scalar(items.get(1), where, "label");
        ValueType type = typeName(items.get(2), where);
        Map<String, Object> ext = items.size() == 4 ? valueExtensions(items.get(3), where, type, TELEMETRY_EXTENSIONS)
                : Map.of();
        Limits limits = null;
        if (ext.containsKey("limits")) {
            try {
                limits = Limits.parse(ext.get("limits"), type);
            } catch (IllegalArgumentException e) {
                throw fail(items.get(3), where, e.getMessage());
            }
        }
        return new Telemetry(itemId, label, type, (String) ext.get("units"), (Number) ext.get("min"),
                (Number) ext.get("max"), allowedValues(ext), (String) ext.get("description"), limits,
                node.getStartMark().getLine() + 1);
    }

    private SysRep sysrep(Node root) {
        if (!(root instanceof MappingNode mapping)) {
            throw fail(root, "", "a SysRep must be a mapping with id, name, commands, telemetry; got "
                    + describe(root));
        }
        Map<String, Node> fields = new LinkedHashMap<>();
        for (NodeTuple tuple : mapping.getValue()) {
            String key = scalar(tuple.getKeyNode(), "", "key");
            if (!TOP_LEVEL_KEYS.contains(key)) {
                throw fail(tuple.getKeyNode(), "", "unknown key " + PyRepr.of(key) + " (allowed: "
                        + String.join(", ", new TreeSet<>(TOP_LEVEL_KEYS)) + ")");
            }
            if (fields.containsKey(key)) {
                throw fail(tuple.getKeyNode(), "", "duplicate key " + PyRepr.of(key));
            }
            fields.put(key, tuple.getValueNode());
        }
        for (String required : List.of("id", "name")) {
            if (!fields.containsKey(required)) {
                throw fail(root, "", "missing required key " + PyRepr.of(required));
            }
        }
        String sysrepId = identifier(fields.get("id"), "id", "id");
        String name = scalar(fields.get("name"), "name", "name");
        List<Command> commands = entries(fields.get("commands"), "commands", this::command, Command::id);
        List<Telemetry> telemetry = entries(fields.get("telemetry"), "telemetry", this::telemetry, Telemetry::id);
        String description = fields.containsKey("description")
                ? scalar(fields.get("description"), "description", "description") : null;
        String version = fields.containsKey("version") ? scalar(fields.get("version"), "version", "version") : null;
        return new SysRep(sysrepId, name, commands, telemetry, path, description, version);
    }

    private <T> List<T> entries(Node node, String section, BiFunction<Node, Integer, T> read,
            java.util.function.Function<T, String> idOf) {
        if (node == null || node instanceof ScalarNode && Tag.NULL.equals(node.getTag())) {
            return List.of();
        }
        if (!(node instanceof SequenceNode sequence)) {
            throw fail(node, section, section + " must be a list, got " + describe(node));
        }
        List<T> entries = new ArrayList<>();
        int index = 0;
        for (Node entryNode : sequence.getValue()) {
            T entry = read.apply(entryNode, index);
            String id = idOf.apply(entry);
            if (entries.stream().anyMatch(e -> idOf.apply(e).equals(id))) {
                throw fail(entryNode, section + "[" + index + "] " + PyRepr.of(id), "duplicate id " + PyRepr.of(id));
            }
            entries.add(entry);
            index++;
        }
        return entries;
    }

    private static String describe(Node node) {
        if (node == null) {
            return "nothing";
        }
        if (node instanceof SequenceNode sequence) {
            return "a list of " + sequence.getValue().size() + " items";
        }
        if (node instanceof MappingNode) {
            return "a mapping";
        }
        if (Tag.NULL.equals(node.getTag())) {
            return "nothing";
        }
        String tag = node.getTag().getValue();
        String kind = tag.substring(tag.lastIndexOf(':') + 1);
        return kind + " " + PyRepr.of(((ScalarNode) node).getValue());
    }

    /** Turns a YAML node into plain Java values, the way a safe load would. */
    private static final class NodeValues extends SafeConstructor {
        private NodeValues() {
            super(new LoaderOptions());
        }

        static Object of(Node node) {
            return normalise(new NodeValues().constructDocument(node));
        }

        /** Integers become Long (Long.MAX_VALUE is plenty for SysRep limits), lists and maps recurse. */
        private static Object normalise(Object value) {
            if (value instanceof Integer number) {
                return number.longValue();
            }
            if (value instanceof BigInteger number) {
                return number.doubleValue();
            }
            if (value instanceof List<?> list) {
                List<Object> out = new ArrayList<>();
                list.forEach(v -> out.add(normalise(v)));
                return out;
            }
            if (value instanceof Map<?, ?> map) {
                Map<Object, Object> out = new LinkedHashMap<>();
                map.forEach((k, v) -> out.put(normalise(k), normalise(v)));
                return out;
            }
            return value;
        }
    }
}
