"""The Class tab: the teacher's view of a classroom (``serve --classroom``).

Only the teacher's tab has it (the page at the teacher's address). It lists the
students connected (a short id each, their grid, model, threshold, where they are in
the lesson and how their answers went), and offers:

- **Send my view to everyone**: the teacher's cloud, map settings and camera go to
  every student's tab;
- **Follow me**: while ticked, every map the teacher shows is shown in every
  student's tab too (until the box is cleared);
- **Show this student's view**: the chosen student's cloud, settings and camera
  in the teacher's tab.

The classroom itself (:class:`rough_viewer.app.host.ClassService`) does the work;
this tab only asks it, through jobs.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import ClassVar

import viser

from rough_viewer.app.binding import Binding
from rough_viewer.app.host import ClassService, Host, Student
from rough_viewer.app.markup import md
from rough_viewer.app.worker import Job, Run

L_SEND = "Send my view to everyone"
L_FOLLOW = "Follow me"
L_STUDENT = "Student"
L_SHOW = "Show this student's view"
NOBODY = "(no students yet)"


def students_table(students: list[Student]) -> str:
    """The students as a Markdown table (one row each), or a line saying there are none.

    >>> from rough_viewer.app.host import Student
    >>> print(students_table([Student("S1", 3, 0.25, "ols", 0.05, "y", False)]))
    **1 student**
    <BLANKLINE>
    | id | grid | model | threshold | axis | lesson | answers |
    |---|---|---|---|---|---|---|
    | S1 | 0.25 m | OLS | 0.05 | y | – | – |
    """
    if not students:
        return "**No students yet.** They open the address `serve` printed after *open*."
    head = f"**{len(students)} student{'s' if len(students) != 1 else ''}**"
    rows = ["| id | grid | model | threshold | axis | lesson | answers |",
            "|---|---|---|---|---|---|---|"]
    for s in students:
        rows.append(f"| {md(s.name, max_chars=12)} | {s.cell_size:.4g} m | {s.model.upper()} "
                    f"| {s.threshold:g} | {s.axis} | {md(s.lesson, max_chars=60) or '–'} "
                    f"| {md(s.answers, max_chars=240) or '–'} |")
    return head + "\n\n" + "\n".join(rows)


@dataclass(eq=False)
class ClassTab:
    """The Class tab's controls."""

    host: Host
    service: ClassService
    table: viser.GuiMarkdownHandle
    send: viser.GuiButtonHandle
    follow: viser.GuiCheckboxHandle
    student: viser.GuiDropdownHandle[str]
    show: viser.GuiButtonHandle
    note: viser.GuiMarkdownHandle
    binding: Binding = field(default_factory=Binding)


@dataclass(frozen=True)
class ClassTableJob(Job[Host]):
    """Show the students as they are now."""

    tab: ClassTab = field(compare=False)
    lane: ClassVar[str] = "class-table"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        t = self.tab
        students = t.service.students()
        t.binding.write(t.table, content=students_table(students))
        names = tuple(s.name for s in students) or (NOBODY,)
        if tuple(t.student.options) != names:
            keep = t.student.value if t.student.value in names else names[0]
            t.binding.write(t.student, options=names)
            t.binding.set(t.student, keep)
        t.binding.set(t.follow, t.service.following)
        yield "table"


@dataclass(frozen=True)
class SendViewJob(Job[Host]):
    """The teacher's view to every student."""

    tab: ClassTab = field(compare=False)
    lane: ClassVar[str] = "class-send"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        n = self.tab.service.send_view(ctx)
        self.tab.binding.write(self.tab.note, content=(
            f"Your view went to {n} student{'s' if n != 1 else ''}." if n else
            "No student is connected."))
        yield "sent"


@dataclass(frozen=True)
class FollowJob(Job[Host]):
    """Start or stop the students following the teacher."""

    tab: ClassTab = field(compare=False)
    on: bool
    lane: ClassVar[str] = "class-follow"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        self.tab.service.follow(ctx, self.on)
        self.tab.binding.write(self.tab.note, content=(
            "The students follow your maps (clear *Follow me* to let them go)." if self.on
            else "The students choose their own maps again."))
        yield "follow"


@dataclass(frozen=True)
class ShowStudentJob(Job[Host]):
    """A student's view in the teacher's tab."""

    tab: ClassTab = field(compare=False)
    name: str
    lane: ClassVar[str] = "class-show"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        found = self.tab.service.show_student(ctx, self.name)
        self.tab.binding.write(self.tab.note, content=(
            f"Showing {md(self.name, max_chars=12)}'s view." if found
            else f"{md(self.name, max_chars=12)} is no longer connected."))
        yield "shown"


def mount(host: Host, *, service: ClassService) -> ClassTab:
    """Add the Class tab (the teacher's tab only)."""
    gui = host.gui
    with host.tab("Class"):
        tab = ClassTab(
            host=host, service=service,
            table=gui.add_markdown(students_table([])),
            send=gui.add_button(L_SEND, hint="Your cloud, map and camera in every "
                                "student's tab."),
            follow=gui.add_checkbox(L_FOLLOW, False, hint="While ticked, each map you "
                                    "show is shown to every student."),
            student=gui.add_dropdown(L_STUDENT, (NOBODY,)),
            show=gui.add_button(L_SHOW, hint="The chosen student's cloud, map and camera "
                                "here."),
            note=gui.add_markdown(""),
        )
    host.allow(tab.send, tab.follow, tab.student, tab.show)
    b = tab.binding
    b.on_change([tab.send], lambda _h: host.submit(SendViewJob(tab)))
    b.on_change([tab.follow], lambda _h: host.submit(FollowJob(tab, bool(tab.follow.value))))
    b.on_change([tab.show], lambda _h: host.submit(ShowStudentJob(tab, str(tab.student.value)))
                if tab.student.value != NOBODY else None)
    def changed() -> None:
        host.submit(ClassTableJob(tab))

    service.on_change(host, changed)
    host.submit(ClassTableJob(tab))
    return tab
