package caretaker.sysrep;

/**
 * A SysRep file is malformed. The message is one line, {@code file:line: where: problem}, the
 * same text the Python loader produces.
 */
public class SysRepException extends RuntimeException {
    private static final long serialVersionUID = 1L;
    private final String path;
    private final int line;
    private final String where;
    private final String problem;

    /**
     * @param path the file
     * @param line the 1-based line, 0 when unknown
     * @param where the entry, e.g. {@code commands[0] 'go'}, or ""
     * @param problem what is wrong and what to do
     */
    public SysRepException(String path, int line, String where, String problem) {
        super(format(path, line, where, problem));
        this.path = path;
        this.line = line;
        this.where = where;
        this.problem = problem;
    }

    private static String format(String path, int line, String where, String problem) {
        String location = line != 0 ? path + ":" + line : path;
        return where.isEmpty() ? location + ": " + problem : location + ": " + where + ": " + problem;
    }

    /** @return the file */
    public String getPath() {
        return path;
    }

    /** @return the 1-based line, 0 when unknown */
    public int getLine() {
        return line;
    }

    /** @return the entry concerned, or "" */
    public String getWhere() {
        return where;
    }

    /** @return what is wrong */
    public String getProblem() {
        return problem;
    }
}
