#pragma once

// How worker threads hand results to the GUI thread. A Mailbox lives on the GUI thread (a child of
// the object it serves); post() may be called from any thread and runs the function there, from
// the event loop, or never if the mailbox is deleted first (Qt drops events posted to a deleted
// object). This is QMetaObject::invokeMethod with Qt::QueuedConnection, with one difference: the
// hand-over is visible to ThreadSanitizer. Debian's Qt is not built with -fsanitize=thread and its
// event queue synchronises on a futex TSan cannot see, so with invokeMethod every capture of a
// queued call is reported as raced between the worker and the GUI thread. The mailbox posts a
// QEvent it has completely built, releases it for TSan just before Qt takes it and acquires it
// before running or destroying it, so the tsan build checks the GUI code as it checks the engine.

#include <QEvent>
#include <QObject>
#include <utility>

namespace saker::ui {

class Mailbox : public QObject {
 public:
  explicit Mailbox(QObject* parent = nullptr) : QObject(parent) {}

  // Runs `fn()` on this object's thread. Thread-safe; `fn` is moved to the GUI thread and
  // destroyed there, after it ran or when the mailbox is deleted with the call still pending.
  template <typename F>
  void post(F fn) {
    send(new Call<F>(std::move(fn)));
  }

 protected:
  void customEvent(QEvent* event) override;

 private:
  class Letter : public QEvent {
   public:
    Letter();
    virtual void run() = 0;
  };
  template <typename F>
  class Call final : public Letter {
   public:
    explicit Call(F fn) : fn_(std::move(fn)) {}
    // Also reached without run(): a mailbox deleted with this call pending.
    ~Call() override { Received(this); }
    void run() override { fn_(); }

   private:
    F fn_;
  };

  // The happens-before edge for ThreadSanitizer (no-ops in other builds).
  static void Sent(const QEvent* letter);
  static void Received(const QEvent* letter);
  void send(Letter* letter);
};

}  // namespace saker::ui
