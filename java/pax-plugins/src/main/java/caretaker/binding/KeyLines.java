package caretaker.binding;

import java.io.StringReader;
import java.util.HashMap;
import java.util.Map;
import org.yaml.snakeyaml.LoaderOptions;
import org.yaml.snakeyaml.Yaml;
import org.yaml.snakeyaml.constructor.SafeConstructor;
import org.yaml.snakeyaml.nodes.MappingNode;
import org.yaml.snakeyaml.nodes.Node;
import org.yaml.snakeyaml.nodes.NodeTuple;
import org.yaml.snakeyaml.nodes.ScalarNode;

/**
 * The line of every mapping key of a YAML text, by dotted path ({@code link.outage_budget}), so an
 * error can name the line to fix. Keys inside lists are not indexed.
 */
final class KeyLines {
    private final Map<String, Integer> lines = new HashMap<>();

    /** @param text YAML that already parsed once (so composing it cannot fail) */
    KeyLines(String text) {
        Node root = new Yaml(new SafeConstructor(new LoaderOptions())).compose(new StringReader(text));
        if (root instanceof MappingNode mapping) {
            index("", mapping);
        }
    }

    private void index(String prefix, MappingNode mapping) {
        for (NodeTuple tuple : mapping.getValue()) {
            if (tuple.getKeyNode() instanceof ScalarNode key) {
                String path = prefix + key.getValue();
                lines.put(path, key.getStartMark().getLine() + 1);
                if (tuple.getValueNode() instanceof MappingNode inner) {
                    index(path + ".", inner);
                }
            }
        }
    }

    /**
     * @param file the file, for the message
     * @param path a dotted key path
     * @return {@code file:line: path} (without the line when the key is not in the text)
     */
    String where(String file, String path) {
        Integer line = lines.get(path);
        return file + (line == null ? "" : ":" + line) + ": " + path;
    }
}
