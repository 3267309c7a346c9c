package caretaker;

import java.nio.file.Path;

/** Where the repository's shared files are, for tests that read them (fixtures, SysReps, bindings). */
public final class Repo {
    private Repo() {
    }

    /** @return the repository root, passed by surefire as caretaker.repo (pom.xml) */
    public static Path root() {
        String root = System.getProperty("caretaker.repo");
        return (root != null ? Path.of(root) : Path.of("../..")).toAbsolutePath().normalize();
    }

    /**
     * @param relative a path inside the repository
     * @return it resolved against the root
     */
    public static Path path(String relative) {
        return root().resolve(relative);
    }
}
