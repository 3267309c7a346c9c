package caretaker.pax;

/** What became of a command. Only SUCCEEDED is success; UNKNOWN is neither success nor failure. */
public enum Outcome {
    /** The system carried the command out and said so. */
    SUCCEEDED,
    /** The system refused or failed it and said so, or it was certainly never executed. */
    FAILED,
    /** It may or may not have been executed, and the system could not be asked: an operator decides. */
    UNKNOWN,
    /** It was stopped by a halt before it finished. */
    HALTED
}
