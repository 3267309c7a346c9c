package caretaker.binding;

import caretaker.pax.PluginOptions;
import caretaker.rosbridge.CaTrust;
import caretaker.rosbridge.LinkOptions;
import caretaker.rosbridge.RosAuth;
import caretaker.sysrep.SysRep;
import caretaker.sysrep.SysRepException;
import caretaker.sysrep.SysRepLoader;
import java.io.IOException;
import java.net.URI;
import java.net.URISyntaxException;
import java.nio.charset.StandardCharsets;
import java.nio.file.Files;
import java.nio.file.Path;
import java.time.Duration;
import java.util.ArrayList;
import java.util.HashSet;
import java.util.List;
import java.util.Map;
import java.util.Set;
import java.util.TreeSet;
import javax.net.ssl.SSLContext;
import org.yaml.snakeyaml.LoaderOptions;
import org.yaml.snakeyaml.Yaml;
import org.yaml.snakeyaml.constructor.SafeConstructor;
import org.yaml.snakeyaml.error.YAMLException;

/**
 * Reads binding files:
 *
 * <pre>
 * robot: iva
 * rosbridge: wss://habitat:9090         # the robot's rosbridge server
 * link:                                 # optional; defaults fit loopback; stating it makes the
 *   one_way_delay: 1.3                  # s   habitat's command ledger mandatory
 *   outage_budget: 120                  # s a command in flight waits for a lost link
 * ledger_namespace: /iva                # optional: where the habitat's command ledger is (default /)
 * security:                             # optional
 *   ca_file: certs/ca.pem               # CA (PEM) that wss:// trusts
 *   secret_file: secrets/bridge.secret  # HMAC auth with the bridge's secret (or token_file)
 * systems:
 * - sysrep: ../affordance_templates.yaml   # relative to this file
 *   plugins: [at_commands, at_telemetry]
 *   namespace: /affordance_template_server
 *   options: {stale_after: 2.0}
 * - sysrep: ../cdra.yaml
 *   plugins: [ros_convention]
 *   namespace: /cdra
 * </pre>
 *
 * An entry may override {@code rosbridge}. SysRep and security paths are relative to the binding
 * file. Errors in {@code link} and {@code security} name the file, line and key
 * ({@code iva.yaml:4: link.outage_budget: ...}).
 */
public final class BindingLoader {
    private static final Set<String> TOP_LEVEL_KEYS = Set.of("robot", "rosbridge", "systems", "description", "link",
            "security", "ledger_namespace");
    private static final Set<String> LINK_KEYS = Set.of("one_way_delay", "outage_budget");
    private static final Set<String> SECURITY_KEYS = Set.of("ca_file", "secret_file", "token_file");
    private static final Set<String> ENTRY_KEYS = Set.of("sysrep", "plugins", "namespace", "options", "rosbridge");

    private BindingLoader() {
    }

    /**
     * @param file the binding file
     * @param rosbridgeOverride replaces every rosbridge URL of the file (e.g. a test's port), or null
     * @return the binding, with its SysReps loaded
     * @throws BindingException the file or an entry is wrong
     * @throws SysRepException a SysRep it names is invalid
     */
    public static Binding load(Path file, URI rosbridgeOverride) {
        String path = file.toString();
        Object root;
        String text;
        try {
            text = Files.readString(file, StandardCharsets.UTF_8);
            root = new Yaml(new SafeConstructor(new LoaderOptions())).load(text);
        } catch (IOException e) {
            throw new BindingException(path + ": cannot read: " + e.getMessage(), e);
        } catch (YAMLException e) {
            throw new BindingException(path + ": not valid YAML: " + e.getMessage().replace('\n', ' '), e);
        }
        if (!(root instanceof Map<?, ?> top)) {
            throw new BindingException(path + ": a binding must be a mapping with robot, rosbridge, systems");
        }
        requireKeys(path, "", top, TOP_LEVEL_KEYS);
        String robot = string(path, "robot", top.get("robot"));
        URI defaultBridge = rosbridgeOverride != null ? rosbridgeOverride
                : top.containsKey("rosbridge") ? uri(path, "rosbridge", top.get("rosbridge")) : null;
        if (!(top.get("systems") instanceof List<?> entries) || entries.isEmpty()) {
            throw new BindingException(path + ": systems: must be a non-empty list of {sysrep, plugins, namespace}");
        }
        List<SystemBinding> systems = new ArrayList<>();
        Set<String> ids = new HashSet<>();
        for (int index = 0; index < entries.size(); index++) {
            String where = "systems[" + index + "]";
            SystemBinding system = entry(file, where, entries.get(index), defaultBridge, rosbridgeOverride);
            if (!ids.add(system.sysRep().id())) {
                throw new BindingException(path + ": " + where + ": SysRep '" + system.sysRep().id()
                        + "' is bound twice; bind each SysRep once (list several plugins instead)");
            }
            systems.add(system);
        }
        KeyLines lines = new KeyLines(text);
        LinkOptions link = link(path, lines, top.get("link"));
        Map<?, ?> security = section(path, lines, "security", top.get("security"), SECURITY_KEYS);
        return new Binding(robot, systems, path, link, auth(file, lines, security, link), tls(file, lines, security),
                top.get("link") != null, ledgerNamespace(path, lines, top.get("ledger_namespace")));
    }

    private static Map<?, ?> section(String path, KeyLines lines, String name, Object raw, Set<String> keys) {
        if (raw == null) {
            return Map.of();
        }
        if (!(raw instanceof Map<?, ?> map)) {
            throw new BindingException(lines.where(path, name) + ": must be a mapping of "
                    + String.join(", ", new TreeSet<>(keys)));
        }
        for (Object key : map.keySet()) {
            if (!keys.contains(String.valueOf(key))) {
                throw new BindingException(lines.where(path, name + "." + key) + ": unknown key (allowed: "
                        + String.join(", ", new TreeSet<>(keys)) + ")");
            }
        }
        return map;
    }

    private static String ledgerNamespace(String path, KeyLines lines, Object raw) {
        if (raw == null) {
            return "";
        }
        if (!(raw instanceof String text) || !text.matches("(/[A-Za-z_][A-Za-z0-9_]*)+|/")) {
            throw new BindingException(lines.where(path, "ledger_namespace") + ": must be a ROS namespace like /iva,"
                    + " got " + raw);
        }
        return text.equals("/") ? "" : text;
    }

    private static LinkOptions link(String path, KeyLines lines, Object raw) {
        Map<?, ?> link = section(path, lines, "link", raw, LINK_KEYS);
        LinkOptions loopback = LinkOptions.loopback();
        Duration delay = seconds(path, lines, "link.one_way_delay", link.get("one_way_delay"), loopback.oneWayDelay(),
                true);
        Duration budget = seconds(path, lines, "link.outage_budget", link.get("outage_budget"),
                loopback.outageBudget(), false);
        return new LinkOptions(delay, budget);
    }

    private static Duration seconds(String path, KeyLines lines, String key, Object value, Duration fallback,
            boolean zeroAllowed) {
        if (value == null) {
            return fallback;
        }
        if (!(value instanceof Number number) || !Double.isFinite(number.doubleValue()) || number.doubleValue() < 0
                || (!zeroAllowed && number.doubleValue() == 0)) {
            throw new BindingException(lines.where(path, key) + ": must be a " + (zeroAllowed ? "" : "positive ")
                    + "number of seconds" + (zeroAllowed ? " (0 or more)" : "") + ", got " + value);
        }
        return Duration.ofNanos(Math.round(number.doubleValue() * 1e9));
    }

    private static RosAuth auth(Path file, KeyLines lines, Map<?, ?> security, LinkOptions link) {
        if (security.containsKey("secret_file") && security.containsKey("token_file")) {
            throw new BindingException(lines.where(file.toString(), "security.token_file")
                    + ": give secret_file (HMAC) or token_file (bearer token), not both");
        }
        if (security.containsKey("secret_file")) {
            return RosAuth.hmac(secret(file, lines, "security.secret_file", security.get("secret_file")),
                    link.loginValidity());
        }
        if (security.containsKey("token_file")) {
            return RosAuth.token(secret(file, lines, "security.token_file", security.get("token_file")));
        }
        return null;
    }

    private static String secret(Path file, KeyLines lines, String key, Object value) {
        Path secretFile = relative(file, lines, key, value);
        String secret;
        try {
            secret = Files.readString(secretFile, StandardCharsets.UTF_8).strip();
        } catch (IOException e) {
            throw new BindingException(lines.where(file.toString(), key) + ": cannot read " + secretFile + " ("
                    + e.getClass().getSimpleName() + ")", e);
        }
        if (secret.isEmpty()) {
            throw new BindingException(lines.where(file.toString(), key) + ": " + secretFile
                    + " is empty; put the bridge's shared secret in it");
        }
        return secret;
    }

    private static SSLContext tls(Path file, KeyLines lines, Map<?, ?> security) {
        if (!security.containsKey("ca_file")) {
            return null;
        }
        try {
            return CaTrust.trusting(relative(file, lines, "security.ca_file", security.get("ca_file")));
        } catch (IllegalArgumentException e) {
            throw new BindingException(lines.where(file.toString(), "security.ca_file") + ": " + e.getMessage(), e);
        }
    }

    private static Path relative(Path file, KeyLines lines, String key, Object value) {
        if (!(value instanceof String text) || text.isEmpty()) {
            throw new BindingException(lines.where(file.toString(), key) + ": must be a file path (relative to the"
                    + " binding), got " + value);
        }
        return file.toAbsolutePath().getParent().resolve(text).normalize();
    }

    private static SystemBinding entry(Path file, String where, Object raw, URI defaultBridge, URI override) {
        String path = file.toString();
        if (!(raw instanceof Map<?, ?> entry)) {
            throw new BindingException(path + ": " + where + ": must be a mapping {sysrep, plugins, namespace}");
        }
        requireKeys(path, where, entry, ENTRY_KEYS);
        Path sysrepFile = file.toAbsolutePath().getParent().resolve(string(path, where + ".sysrep",
                entry.get("sysrep"))).normalize();
        SysRep sysRep = SysRepLoader.load(sysrepFile);
        if (!(entry.get("plugins") instanceof List<?> pluginList) || pluginList.isEmpty()) {
            throw new BindingException(path + ": " + where + ".plugins: must be a non-empty list of plugin names ("
                    + String.join(", ", PluginKind.names()) + ", or a class name)");
        }
        List<String> plugins = new ArrayList<>();
        for (Object plugin : pluginList) {
            String name = string(path, where + ".plugins", plugin);
            if (!PluginKind.names().contains(name) && !name.contains(".")) {
                throw new BindingException(path + ": " + where + ": unknown plugin '" + name + "' (built in: "
                        + String.join(", ", PluginKind.names()) + "; or a class name)");
            }
            plugins.add(name);
        }
        String namespace = entry.containsKey("namespace") ? string(path, where + ".namespace", entry.get("namespace"))
                : "";
        URI bridge = override != null ? override
                : entry.containsKey("rosbridge") ? uri(path, where + ".rosbridge", entry.get("rosbridge")) : defaultBridge;
        if (bridge == null) {
            throw new BindingException(path + ": " + where + ": no rosbridge URL (set rosbridge at the top or here)");
        }
        Object options = entry.containsKey("options") ? entry.get("options") : Map.of();
        if (!(options instanceof Map<?, ?> optionMap)) {
            throw new BindingException(path + ": " + where + ".options: must be a mapping");
        }
        Map<String, Object> typed = new java.util.LinkedHashMap<>();
        optionMap.forEach((key, value) -> typed.put(String.valueOf(key), value));
        PluginOptions pluginOptions = new PluginOptions(typed, path + ": " + where);
        try {
            PluginKind.checkOptions(plugins, pluginOptions);
        } catch (caretaker.pax.PluginException e) {
            throw new BindingException(e.getMessage(), e);
        }
        return new SystemBinding(sysRep, plugins, bridge, namespace, pluginOptions, path + ": " + where);
    }

    private static void requireKeys(String path, String where, Map<?, ?> map, Set<String> allowed) {
        for (Object key : map.keySet()) {
            if (!allowed.contains(String.valueOf(key))) {
                throw new BindingException(path + ": " + (where.isEmpty() ? "" : where + ": ") + "unknown key '" + key
                        + "' (allowed: " + String.join(", ", new TreeSet<>(allowed)) + ")");
            }
        }
    }

    private static String string(String path, String where, Object value) {
        if (!(value instanceof String text) || text.isEmpty()) {
            throw new BindingException(path + ": " + where + ": must be a non-empty string, got " + value);
        }
        return text;
    }

    private static URI uri(String path, String where, Object value) {
        String text = string(path, where, value);
        try {
            URI uri = new URI(text);
            if (!"ws".equals(uri.getScheme()) && !"wss".equals(uri.getScheme()) || uri.getPort() < 0) {
                throw new URISyntaxException(text, "expected ws://HOST:PORT");
            }
            return uri;
        } catch (URISyntaxException e) {
            throw new BindingException(path + ": " + where + ": '" + text + "' is not a rosbridge URL like"
                    + " ws://127.0.0.1:9090", e);
        }
    }
}
