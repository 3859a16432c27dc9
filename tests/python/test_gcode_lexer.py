"""G-code front end (contour.gcode.lexer/expr/params/flow): text -> evaluated
blocks, RS-274/NGC as LinuxCNC reads it."""

import io
import math

import pytest
from contour.gcode import GcodeError, flow
from contour.gcode.lexer import LINE_CAP, Block, blocks, file_lines
from contour.gcode.params import Params


class Rep:
    path = "t.ngc"

    def __init__(self):
        self.skipped = []

    def skip(self, kind, line, note=""):
        self.skipped.append((kind, line))

    def error(self, line, message):
        return GcodeError(self.path, line, message)


def run(text, params=None, rep=None):
    lines = text.split("\n") if isinstance(text, str) else text
    return list(blocks(lines, params or Params(), rep or Rep()))


def words(text, **kw):
    return [(b.line, b.words) for b in run(text, **kw)]


def err(text, **kw):
    with pytest.raises(GcodeError) as exc:
        run(text, **kw)
    return exc.value


def value(expr):
    """The value of one expression, through a word."""
    (b,) = run(f"G1 X{expr}")
    return b.words[1][1]


# ---- lines, words, comments -----------------------------------------------


def test_plain_lines_lowercase_and_line_numbers():
    assert words("N10 G1 X1.5 Y-.5 F300\n\nn20 g0 x2 z1.\nN30") == [
        (1, [("G", 1.0), ("X", 1.5), ("Y", -0.5), ("F", 300.0)]),
        (3, [("G", 0.0), ("X", 2.0), ("Z", 1.0)]),
    ]


def test_fast_and_general_paths_give_the_same_words():
    plain = words("N1 G1 X1 Y2 F100\nX3")
    noisy = words("N1 G1 X1 (c) Y2 F100 ; tail\nX 3")
    assert plain == noisy


def test_spaces_anywhere_outside_comments():
    # LinuxCNC's own example: 'G0X +0. 12 34Y 7' is 'G0 X0.1234 Y7'.
    assert words("G0X +0. 12 34Y 7") == [(1, [("G", 0.0), ("X", 0.1234), ("Y", 7.0)])]


def test_compact_words():
    assert words("G1X1Y2F4") == [(1, [("G", 1.0), ("X", 1.0), ("Y", 2.0), ("F", 4.0)])]


@pytest.mark.parametrize(
    "text,message",
    [
        ("G1 X1 (a (nested) comment)", "'(' inside a comment"),
        ("G1 X1 (open comment", "unclosed comment"),
        ("S(speed)100", "malformed number in 'S'"),
        ("G1 X ABS Y1", "value expected at 'ABS' after X"),
        ("G1 XNAN", "malformed word 'XNAN': X has no value"),
        ("G1 YINF", "malformed word 'YINF': Y has no value"),
        ("G1 XY5", "malformed word 'XY5': X has no value"),
        ("GOO", "malformed word 'GOO': G has no value (letter O written for zero?)"),
        ("G1 X1.2.3", "malformed number in 'X1.2.3'"),
        ("G1 X-", "malformed number in 'X-'"),
        ("G1 X- F100", "malformed number in 'X-'"),
        ("G1 X F100", "value expected at 'F100' after X"),
        ("G1 X", "malformed number in 'X'"),
        ("G1 X12-3", "malformed number in 'X12-3'"),
        ("G1 X" + "9" * 400, "number too large"),
        ("G1 X1 @2", "polar coordinates"),
        ("G1 X1 N10", "line number 'N10' must begin the line"),
        ("G1 X1 O100", "an O-word must begin its line"),
        ("G1 X\x002", "malformed number"),
        ("G1 X1 Y\x00", "malformed number"),
        ("G1 X1 \x00", "control character 0x00"),
        ("G1 X1 é", "unexpected character 'é'"),
        ("#1 G1", "'=' expected after parameter"),
        ("FOO", "malformed word 'FOO': F has no value"),
        ("$", "unknown word '$'"),
        ("G1 X1 _", "unknown word '_'"),
    ],
)
def test_malformed_words_are_line_errors(text, message):
    e = err("G21\n; fine\n" + text)
    assert e.line == 3
    assert message in e.message
    assert str(e).startswith("t.ngc:3: ")


def test_exponent_is_not_a_number_but_an_e_word():
    # RS-274/NGC has no exponents: X1e5 is X1 and an E word (the
    # interpreter refuses E); never X100000.
    assert words("G1 X1E5") == [(1, [("G", 1.0), ("X", 1.0), ("E", 5.0)])]


def test_messages_and_only_the_last_comment_is_active():
    bs = run("(MSG, Hello World)\nG0 X1 (msg,second)\n(msg,first) (plain)\n(DEBUG,x)")
    assert [(b.line, list(b.messages)) for b in bs] == [
        (1, ["Hello World"]),
        (2, ["second"]),
        (4, ["x"]),
    ]


def test_debug_and_print_substitute_parameters():
    bs = run(
        "#1=2.5\n#<size>=3\n(DEBUG, a=#1 b=#<S i Z e> %d#1 %.2f#1 #<nope>)\n(MSG, m=#1)\n(PRINT,#2)"
    )
    assert list(bs[0].messages) == ["a=2.500000 b=3.000000 2 2.50 ######"]
    assert list(bs[1].messages) == ["m=#1"]  # MSG prints its text as written
    assert list(bs[2].messages) == ["0.000000"]


def test_block_delete_runs_the_block_and_is_reported():
    rep = Rep()
    assert words("/G1 X1", rep=rep) == [(1, [("G", 1.0), ("X", 1.0)])]
    assert rep.skipped == [("/ (block delete)", 1)]


def test_abort_comment_refuses():
    assert "aborts here: tool broken" in err("G0 X1\n(ABORT, tool broken)").message


def test_percent_marks_the_program():
    assert words("%\nG0 X1\n%\nG0 X2 this is not read\n") == [(2, [("G", 0.0), ("X", 1.0)])]
    assert words("\n  %  \nG0 X1\n%") == [(3, [("G", 0.0), ("X", 1.0)])]


def test_percent_without_closing_percent_is_an_error():
    e = err("%\nG0 X1\nG0 X2")
    assert "neither a closing % line nor M2/M30" in e.message


@pytest.mark.parametrize("end", ["M30", "m2", "M02 (end)", "G0 X0 M30 ; done"])
def test_percent_without_closing_percent_but_m2_m30_is_a_program(end):
    assert len(run(f"%\nG0 X1\n{end}\nG0 X3")) == 3


def test_sinumerik_file_header_is_reported():
    rep = Rep()
    assert words("%_N_PART_MPF\n;$PATH=/_N_MPF_DIR\nG0 X1", rep=rep) == [
        (3, [("G", 0.0), ("X", 1.0)])
    ]
    assert rep.skipped == [("%_N_ (file header)", 1)]


def test_percent_inside_the_program_is_reported():
    rep = Rep()
    assert words("G0 X1\n%\nG0 X2", rep=rep) == [
        (1, [("G", 0.0), ("X", 1.0)]),
        (3, [("G", 0.0), ("X", 2.0)]),
    ]
    assert rep.skipped == [("%", 2)]


def test_bom_crlf_and_bytes():
    data = "\ufeffG0 X1\r\nG1 Y2 F5\r\n".encode()
    assert words(data.splitlines(keepends=True)) == [
        (1, [("G", 0.0), ("X", 1.0)]),
        (2, [("G", 1.0), ("Y", 2.0), ("F", 5.0)]),
    ]
    assert words(data.decode().splitlines()) == words(data.splitlines(keepends=True))
    assert words(list(file_lines(io.BytesIO(data)))) == words(data.decode().splitlines())


def test_bom_after_the_first_line_is_an_error():
    assert "byte order mark" in err("G0 X1\n\ufeffG0 X2").message


def test_undecodable_bytes_name_the_line():
    e = err([b"G0 X1\n", b"G0 X\xff\xfe\n"])
    assert e.line == 2 and "not UTF-8" in e.message and "0xff" in e.message
    e = err(["G0 X1", "G0 X" + b"\xff".decode("utf-8", "surrogateescape")])
    assert e.line == 2 and "undecodable" in e.message


def test_ten_million_character_line_is_refused_without_holding_it():
    e = err(["G0 X1", "G1 X" + "1" * 10_000_000])
    assert e.line == 2 and f"longer than {LINE_CAP}" in e.message
    # From a file, at most cap+1 bytes of the line are ever read.
    data = b"G0 X1\n" + b"(" + b"x" * 10_000_000 + b")\nG0 X2\n"
    chunks = list(file_lines(io.BytesIO(data)))
    assert max(len(c) for c in chunks) == LINE_CAP + 2
    assert err(chunks).line == 2


def test_line_at_the_cap_is_read():
    at_cap = "G0 X1 (" + "x" * (LINE_CAP - 8) + ")"
    assert len(at_cap) == LINE_CAP
    assert words([at_cap + "\r\n"]) == [(1, [("G", 0.0), ("X", 1.0)])]
    data = (at_cap + "\r\nG0 X2\r\n").encode()
    assert words(list(file_lines(io.BytesIO(data)))) == [
        (1, [("G", 0.0), ("X", 1.0)]),
        (2, [("G", 0.0), ("X", 2.0)]),
    ]
    assert "longer than" in err([at_cap + "x"]).message


# ---- expressions ------------------------------------------------------------


@pytest.mark.parametrize(
    "expr,expected",
    [
        ("[1+2*3]", 7.0),
        ("[2**3**2]", 64.0),  # left to right within a group, as LinuxCNC: [2**3]**2
        ("[2*3**2]", 18.0),  # ** above *
        ("[2.0/3*1.5-5.5/11.0]", 0.5),  # LinuxCNC's own example
        ("[10-4-3]", 3.0),
        ("[12/2/3]", 2.0),
        ("[1+2 EQ 3]", 1.0),  # comparison below +
        ("[1 OR 0 AND 0]", 0.0),  # AND OR XOR one group, left to right
        ("[0 AND 1 OR 1]", 1.0),
        ("[1 XOR 1]", 0.0),
        ("[2 GT 1 AND 3 LT 2]", 0.0),
        ("[7 MOD 3]", 1.0),
        ("[10-7 MOD 4]", 7.0),  # MOD above -
        ("[2*3 GT 5]", 1.0),
        ("[-7 MOD 3]", 2.0),
        ("[7.5 MOD 2]", 1.5),
        ("[1 EQ 1.0000001]", 1.0),  # TOLERANCE_EQUAL 1e-6
        ("[1 NE 1.00001]", 1.0),
        ("[2 GE 2]", 1.0),
        ("[2 LE 1]", 0.0),
        ("[-[2]]", -2.0),
        ("[1 + acos[0] - [2 ** [4.0/2]]]", 87.0),
        ("SIN[30]", 0.5),
        ("COS[60]", 0.5),
        ("TAN[45]", 1.0),
        ("ASIN[1]", 90.0),
        ("ACOS[0]", 90.0),
        ("ATAN[1]/[1]", 45.0),
        ("ATAN[1]/[-1]", 135.0),
        ("ATAN[-1]/[-1]", -135.0),
        ("ABS[-3]", 3.0),
        ("EXP[0]", 1.0),
        ("LN[1]", 0.0),
        ("SQRT[16]", 4.0),
        ("FIX[2.8]", 2.0),
        ("FIX[-2.8]", -3.0),
        ("FUP[2.8]", 3.0),
        ("FUP[-2.8]", -2.0),
        ("ROUND[2.5]", 3.0),
        ("ROUND[-2.5]", -3.0),
        ("ROUND[2.4]", 2.0),
        ("[EXISTS[#<nope>]]", 0.0),
    ],
)
def test_expressions(expr, expected):
    assert value(expr) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize(
    "expr,message",
    [
        ("SQRT[-1]", "SQRT[-1]: negative argument"),
        ("[1/0]", "division by zero"),
        ("[1 MOD 0]", "MOD 0"),
        ("LN[0]", "LN[0]: argument must be positive"),
        ("LN[-1]", "LN[-1]"),
        ("ACOS[2]", "ACOS[2]: argument outside -1..1"),
        ("ASIN[-1.5]", "ASIN[-1.5]"),
        ("EXP[1000]", "EXP[1000] is not a finite number"),
        ("[0**-1]", "zero to a negative power"),
        ("[-8**0.5]", "negative number to a non-integer power"),
        ("[10**400]", "not a finite number"),
        ("ATAN[1]", "ATAN needs two arguments"),
        ("[1+2", "unclosed expression"),
        ("[1 [2]]", "operator or ']' expected"),
        ("[1 2 +]", "value expected"),  # '1 2' is the number 12
        ("[1+]", "value expected"),
        ("EXISTS[#1]", "EXISTS takes one named parameter"),
        ("[" * 40 + "1" + "]" * 40, "nested deeper than"),
        ("#" * 40 + "1", "nested deeper than"),
        ("-" * 40 + "1", "malformed number"),
    ],
)
def test_expression_errors_name_the_problem(expr, message):
    e = err(f"G0 X0\nG1 X{expr}")
    assert e.line == 2
    assert message in e.message


def test_value_of_the_last_call_reads_zero_before_any_call():
    assert value("[#<_value> + #<_value_returned>]") == 0.0


def test_exists_sees_named_parameters():
    assert value("[EXISTS[#<a>]]") == 0.0
    (b,) = run("#<a>=1\nG1 X[EXISTS[#<A>]]")
    assert b.words[1] == ("X", 1.0)


# ---- parameters --------------------------------------------------------------


def test_reads_on_a_line_see_values_before_its_assignments():
    assert words("#1=5\n#1=1 #2=[#1+1]\nG1 X#2 Y#1") == [(3, [("G", 1.0), ("X", 6.0), ("Y", 1.0)])]
    # LinuxCNC's example: '#3=6 G1 X#3' moves to the old #3.
    assert words("#3=15\n#3=6 G1 X#3\nG1 X#3")[0] == (2, [("G", 1.0), ("X", 15.0)])
    assert words("#3=15\n#3=6 G1 X#3\nG1 X#3")[1] == (3, [("G", 1.0), ("X", 6.0)])


def test_named_parameter_read_before_assigned_on_its_line_is_an_error():
    e = err("#<a>=1 #<b>=[#<a>+1]")
    assert e.line == 1 and "#<a> read before it is set" in e.message


def test_numbered_parameters_read_zero_and_indirection():
    assert words("#2=7\n#7=3.5\nG1 X#9 Y##2 Z#[3+4]") == [
        (3, [("G", 1.0), ("X", 0.0), ("Y", 3.5), ("Z", 3.5)])
    ]


def test_hash_binds_tighter_than_operators():
    assert value("[#1+2]") == 2.0  # #1 (0) plus 2, not #3


@pytest.mark.parametrize("text", ["#0=1", "#5603=1", "G1 X#5603", "#1.5=2"])
def test_numbered_parameter_out_of_range_or_fractional(text):
    e = err(text)
    assert "parameter number" in e.message


def test_named_parameters_fold_case_and_spaces():
    assert words("#<P a R am>=4\nG1 X#<param>") == [(2, [("G", 1.0), ("X", 4.0)])]


def test_parameter_values_follow_the_interpreter_between_blocks():
    # The generator is lazy: what the interpreter sets after block k is
    # seen by block k+1.
    params = Params()
    gen = blocks(["G1 X1", "G1 X[#5420+1]"], params, Rep())
    assert next(gen).words[1] == ("X", 1.0)
    params.set(5420, 1.0)
    assert next(gen).words[1] == ("X", 2.0)


def test_system_hook_gives_read_only_named_parameters():
    params = Params(system=lambda name: 3.0 if name == "_x" else None)
    assert words("G1 X[#<_x>*2]", params=params) == [(1, [("G", 1.0), ("X", 6.0)])]
    e = err("#<_x>=1", params=Params(system=lambda name: 3.0 if name == "_x" else None))
    assert "read-only" in e.message


# ---- O-word control flow -----------------------------------------------------


def xs(text, **kw):
    return [dict(b.words).get("X") for b in run(text, **kw) if b.words]


def test_while_loop():
    assert xs("#1=0\no101 while [#1 LT 3]\nG1 X#1\n#1=[#1+1]\no101 endwhile\nG0 X9") == [
        0.0,
        1.0,
        2.0,
        9.0,
    ]


def test_lines_run_again_keep_their_parameters_and_own_word_lists():
    bs = run("#1=0\no1 repeat [3]\nG1 X[1] Y2\nG1 X#1\n/G1 Z#1\n#1=[#1+1]\no1 endrepeat")
    assert [b.words for b in bs] == [
        [("G", 1.0), ("X", 1.0), ("Y", 2.0)],
        [("G", 1.0), ("X", 0.0)],
        [("G", 1.0), ("Z", 0.0)],
        [("G", 1.0), ("X", 1.0), ("Y", 2.0)],
        [("G", 1.0), ("X", 1.0)],
        [("G", 1.0), ("Z", 1.0)],
        [("G", 1.0), ("X", 1.0), ("Y", 2.0)],
        [("G", 1.0), ("X", 2.0)],
        [("G", 1.0), ("Z", 2.0)],
    ]
    assert bs[0].words is not bs[3].words


def test_while_false_skips_the_body():
    assert xs("o1 while [0]\nG1 X1\no1 endwhile\nG0 X2") == [2.0]


def test_do_while_with_continue():
    text = """#1 = 0
o100 do
  #1 = [#1 + 1]
  o110 if [#1 EQ 2]
    o100 continue
  o110 endif
  G1 X#1
o100 while [#1 LT 4]
G0 X99"""
    assert xs(text) == [1.0, 3.0, 4.0, 99.0]


def test_do_body_runs_once_when_the_condition_is_false():
    assert xs("o1 do\nG1 X1\no1 while [0]\nG0 X2") == [1.0, 2.0]


def test_while_with_break():
    text = """#1=0
o1 while [1]
  #1=[#1+1]
  o2 if [#1 GT 3]
    o1 break
  o2 endif
  G1 X#1
o1 endwhile
G0 X#1"""
    assert xs(text) == [1.0, 2.0, 3.0, 4.0]


def test_repeat_with_break_and_continue():
    text = """#1=0
o5 repeat [5]
  #1=[#1+1]
  o6 if [#1 EQ 2]
    o5 continue
  o6 elseif [#1 EQ 4]
    o5 break
  o6 endif
  G1 X#1
o5 endrepeat
G0 X#1"""
    assert xs(text) == [1.0, 3.0, 4.0]


def test_repeat_zero_times():
    assert xs("o5 repeat [0]\nG1 X1\no5 endrepeat\nG0 X2") == [2.0]


@pytest.mark.parametrize("n,expected", [(7, 100.0), (3, 200.0), (-1, 300.0)])
def test_if_elseif_else(n, expected):
    text = f"""#2={n}
o102 if [#2 GT 5]
  F100
o102 elseif [#2 GE 2]
  F200
o102 else
  F300
o102 endif"""
    assert [dict(b.words)["F"] for b in run(text)] == [expected]


def test_subroutine_arguments_locals_and_return_value():
    text = """#1=11
#2=22
#3=33
o<add> sub
  #<t>=[#1+#2]
  G1 X#<t> Y#3
  #1=99
o<add> return [#<t>*10]
  G0 X1000
o<add> endsub
o<add> call [1] [2]
G0 X#<_value> Y#1 Z#<_value_returned>"""
    bs = run(text)
    assert bs[0].words == [("G", 1.0), ("X", 3.0), ("Y", 33.0)]  # #3 keeps the caller's value
    assert bs[1].words == [("G", 0.0), ("X", 30.0), ("Y", 11.0), ("Z", 1.0)]
    assert len(bs) == 2


def test_caller_named_locals_are_not_visible_in_a_subroutine():
    text = "#<mine>=1\n#<_shared>=2\no1 sub\nG1 X#<_shared>\nG1 X#<mine>\no1 endsub\no1 call"
    e = err(text)
    assert e.line == 5 and "#<mine> read before it is set" in e.message


def test_subroutine_locals_vanish_on_return():
    e = err("o1 sub\n#<t>=1\no1 endsub\no1 call\nG1 X#<t>")
    assert e.line == 5


def test_nested_subroutines_and_numbered_labels():
    text = """o200 sub
  G1 X[#1*10]
o200 endsub
o100 sub
  o200 call [#1+1]
  G1 X#1
o100 endsub
o100 call [2]"""
    assert xs(text) == [30.0, 2.0]


def test_recursion():
    text = """o<fact> sub
  o1 if [#1 LE 1]
    o<fact> return [1]
  o1 endif
  o<fact> call [#1-1]
o<fact> return [#1*#<_value>]
o<fact> endsub
o<fact> call [5]
G1 X#<_value>"""
    assert xs(text) == [120.0]


def test_recursion_depth_is_capped():
    e = err("o1 sub\no1 call\no1 endsub\no1 call")
    assert e.line == 2 and f"deeper than {flow.MAX_CALL_DEPTH}" in e.message


def test_iteration_cap_stops_an_endless_loop(monkeypatch):
    monkeypatch.setattr(flow, "ITERATION_CAP", 50)
    e = err("o1 while [1]\nG1 X1\no1 endwhile")
    assert e.line == 1 and "more than 50 loop passes" in e.message


def test_loop_and_call_count_together_for_the_cap(monkeypatch):
    monkeypatch.setattr(flow, "ITERATION_CAP", 50)
    assert len(xs("o1 repeat [49]\nG1 X1\no1 endrepeat")) == 49
    assert "more than 50" in err("o1 repeat [52]\nG1 X1\no1 endrepeat").message


@pytest.mark.parametrize(
    "text,line,message",
    [
        ("o<nope> call", 1, "o<nope> call: subroutine not defined before this line"),
        ("o1 call\no1 sub\no1 endsub", 1, "not defined before this line"),
        ("o1 sub\nG1 X1", 1, "o1 sub without endsub"),
        ("o1 sub\no2 sub\no2 endsub\no1 endsub", 2, "subroutines do not nest"),
        ("o1 if [1]\nG1 X1", 1, "o1 if without endif"),
        ("o1 if [0]\nG1 X1", 1, "o1 if without"),
        ("o1 while [1]\nG1 X1", 1, "o1 while without endwhile"),
        ("o1 else", 1, "o1 else without if"),
        ("o1 endwhile", 1, "o1 endwhile without while"),
        ("o1 return", 1, "outside a subroutine"),
        ("o1 break", 1, "outside an o1 loop"),
        ("o1 if [1]\no2 while [1]\no1 endif", 3, "o1 endif inside o2 while"),
        ("o1 if [1] G1 X1", 1, "other words are not allowed"),
        ("o1 if", 1, "needs a condition"),
        ("o1 frobnicate", 1, "unknown O-word keyword 'frobnicate'"),
        ("o1 repeat [1.5]\no1 endrepeat", 1, "not an integer"),
        ("o<> call", 1, "empty O-word name"),
    ],
)
def test_control_flow_errors(text, line, message):
    e = err(text)
    assert e.line == line
    assert message.lower() in e.message.lower()


def test_program_number_is_reported_not_a_word():
    rep = Rep()
    assert words("O1000 (PART 1)\nG0 X1", rep=rep) == [(2, [("G", 0.0), ("X", 1.0)])]
    assert rep.skipped == [("O (program number)", 1)]


def test_indirect_o_label():
    assert xs("o3 sub\nG1 X3\no3 endsub\n#101=1\no[#101+2] call") == [3.0]


def test_loop_buffer_is_released_after_the_loop():
    params = Params()
    runner = flow.Runner(
        ["o1 repeat [3]", "G1 X1", "o1 endrepeat"] + ["G1 X2"] * 100, params, Rep()
    )
    params.rep = runner.rep
    gen = runner.run()
    for _ in range(4):
        next(gen)
    assert runner.file.hold == 0
    assert len(runner.file.buf) <= 3
    for _ in gen:
        assert len(runner.file.buf) == 0


def test_memory_stays_flat_for_a_long_plain_file():
    import tracemalloc

    def peak(n):
        def lines():
            for i in range(n):
                yield f"N{i} G1 X{i * 0.001:.3f} Y{(i * 7) % 1000 * 0.01:.2f} F{1000 + i % 7}\n"

        tracemalloc.start()
        count = sum(1 for _ in blocks(lines(), Params(), Rep()))
        p = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert count == n
        return p

    small, large = peak(4_000), peak(16_000)
    assert large < small * 1.3


# ---- dialects --------------------------------------------------------------


@pytest.mark.parametrize(
    "line",
    [
        "0 BEGIN PGM TEST MM",
        "1 BLK FORM 0.1 Z X+0 Y+0 Z-40",
        "TOOL CALL 1 Z S5000",
        "L X+10 R0 FMAX",
        "7 L X+10 Y+5 R0 FMAX M3",
        "CYCL DEF 200 BOHREN",
        "CC X+50 Y+50",
    ],
)
def test_heidenhain_conversational_is_refused_with_a_hint(line):
    e = err(line)
    assert e.line == 1 and "Heidenhain conversational" in e.message


@pytest.mark.parametrize("line", ["%PART G71 *", "N10 G00 G40 G90 *", "N20 G01 X+10 F500 *"])
def test_heidenhain_iso_is_refused_with_a_hint(line):
    e = err(line)
    assert e.line == 1 and "Heidenhain ISO program" in e.message


@pytest.mark.parametrize(
    "line,shown",
    [
        ("GOTOF LABEL1", "'GOTOF'"),
        ("GOTO10", "'GOTO'"),
        ("IF R1>5 GOTOF END", "'IF'"),
        ("DEF REAL LEN", "'DEF'"),
        ("PROC POCKET", "'PROC'"),
        ("REPEAT START END P=3", "'REPEAT'"),
        ("WHILE R1<5", "'WHILE'"),
    ],
)
def test_sinumerik_control_flow_is_refused_with_a_hint(line, shown):
    e = err("G0 X0\n" + line)
    assert e.line == 2 and f"Sinumerik/Fanuc control flow {shown}" in e.message
    assert "O-word" in e.message


def test_sinumerik_labels_and_frames_are_refused():
    assert "jump label 'START:'" in err("START: G1 X1").message
    assert "frame 'TRANS'" in err("TRANS X10").message
    assert "SUPA (machine coordinates" in err("G0 SUPA Z0").message
    assert "DIAMON (diameter programming)" in err("DIAMON").message


def test_sinumerik_words_the_reader_takes():
    params = Params()
    bs = run(
        "R1=50\nR2=R1\nR3=R1*2\nG1 F=R2 X=IC(5) C=DC(90) A=ACN(10)\nF=R3\nCYCLE832(0.01,1)\n"
        'CYCLE832()\nTRAORI\nT="DRILL" M6\n$A_DBB=1',
        params=params,
    )
    assert bs[0].words == [
        ("G", 1.0),
        ("=F", (50.0, None)),
        ("=X", (5.0, "IC")),
        ("=C", (90.0, "DC")),
        ("=A", (10.0, "ACN")),
    ]
    assert bs[1].words == [("=F", (None, "R3"))]  # R3 came from an expression: unknown
    assert bs[2].words == [("CALL", "CYCLE832")] and bs[2].call_args == {"CYCLE832": "0.01,1"}
    assert bs[3].call_args == {"CYCLE832": ""}
    assert bs[4].words == [("IDENT", "TRAORI")]
    assert bs[5].words == [("=T", (None, '"DRILL"')), ("M", 6.0)]
    assert bs[6].words == [("IDENT", "$A_DBB=")]
    assert params.r == {1: 50.0, 2: 50.0}


def test_block_equality_and_repr():
    assert Block(3, [("X", 1.0)]) == Block(3, [("X", 1.0)], [])
    assert "line=3" in repr(Block(3, [("X", 1.0)]))
    assert not math.isnan(run("G1 X1")[0].words[1][1])
