"""common.row_memo: each distinct row computed once, results in the asked order, bounded."""

from common.row_memo import RowMemo


def test_computes_only_unknown_rows_and_keeps_order() -> None:
    asked: list[list[int]] = []
    memo: RowMemo[str] = RowMemo()

    def upper(keys: list[bytes]):
        def compute(rows: list[int]) -> list[str]:
            asked.append(rows)
            return [keys[i].decode().upper() for i in rows]

        return compute

    first = [b"a", b"b", b"c"]
    assert memo.rows(first, upper(first)) == ["A", "B", "C"]
    second = [b"c", b"d", b"a", b"d"]
    assert memo.rows(second, upper(second)) == ["C", "D", "A", "D"]
    assert asked == [[0, 1, 2], [1, 3]]  # a row missing twice in one call is computed for each


def test_clears_when_full() -> None:
    calls = 0
    memo: RowMemo[int] = RowMemo(capacity=2)

    def compute(rows: list[int]) -> list[int]:
        nonlocal calls
        calls += len(rows)
        return rows

    for key in (b"1", b"2", b"3"):
        memo.rows([key], compute)
    memo.rows([b"1"], compute)  # forgotten once the memo held more than its capacity
    assert calls == 4
